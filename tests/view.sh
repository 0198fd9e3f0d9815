#!/bin/sh
# tests/view.sh BUILD - simcluster run --record and simcluster-view(1) as a
# user meets them: a recorded drop renders to PNG files whose pixels show
# the scene (tests/png_check), a camera looking down at a body sees it, and
# bad usage, a missing log and a truncated log fail with one line.
# OSMesa renders offscreen: no display is needed.
run="$1/tools/simcluster"
view="$1/tools/simcluster-view"
png="$1/tests/png_check"
sky=153,191,235            # simcluster-view's clear colour (0.60, 0.75, 0.92)
dir=$(mktemp -d) || exit 1
trap 'rm -rf "$dir"' EXIT
fail=0
# ASan: Mesa's own never-freed framebuffer list is not our leak
LSAN_OPTIONS="suppressions=$PWD/tests/lsan_osmesa.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export LSAN_OPTIONS
. "$(dirname "$0")/cli_lib.sh"

# record: 3 bolts and nuts, 30 frames: 3 shapes (floor, bolt, nut), then 31 states
check "run --record" 0 "$run" run bolts --bodies 3 --frames 30 --workers 1 --record "$dir/log"
grep -q "^bolts: 4 bodies" "$dir/out" || { echo "FAIL: run --record: no report"; fail=1; }
[ -s "$dir/log" ] || { echo "FAIL: run --record: no log"; fail=1; }
check "run --record --json" 0 "$run" run bolts --bodies 3 --frames 5 --record "$dir/log5" --json
grep -q '"frames": 5' "$dir/out" || { echo "FAIL: --record --json: no report"; fail=1; }
check "dump" 0 "$view" --dump "$dir/log"
[ "$(grep -c "^frame " "$dir/out")" -eq $((31 * 4)) ] ||
    { echo "FAIL: dump: $(grep -c "^frame " "$dir/out") lines, expected 124"; fail=1; }
grep -q "^frame 30 body 3 " "$dir/out" || { echo "FAIL: dump: no frame 30"; fail=1; }
check "run --record into a missing directory" 1 "$run" run bolts --frames 1 --record "$dir/no/log"
check "profile --record" 2 "$run" profile bolts --record "$dir/p"

# render every 10th frame at 96x72: frames 0, 10, 20, 30
mkdir "$dir/png"
check "render" 0 "$view" --out "$dir/png" --size 96x72 --every 10 "$dir/log"
[ "$(ls "$dir/png" | wc -l)" -eq 4 ] && [ -f "$dir/png/frame_00030.png" ] ||
    { echo "FAIL: render: files $(ls "$dir/png" | tr '\n' ' ')"; fail=1; }
for f in "$dir"/png/*.png; do
    check "png_check $f" 0 "$png" "$f" 96 72 $sky
    set -- $(cat "$dir/out")    # colours N nonsky F centre R G B CLASS
    [ "${2:-0}" -ge 8 ] || { echo "FAIL: $f: only ${2:-0} colours"; fail=1; }
    [ "$(echo "${4:-0} > 0.5" | bc 2>/dev/null || echo 1)" = 1 ] ||
        { echo "FAIL: $f: mostly sky ($4 not sky)"; fail=1; }
done
check "render --frames" 0 "$view" --out "$dir/png" --size 32x32 --frames 5:6 "$dir/log"
[ -f "$dir/png/frame_00005.png" ] && [ -f "$dir/png/frame_00006.png" ] ||
    { echo "FAIL: --frames 5:6: no frames 5 and 6"; fail=1; }

# a camera 0.3 m above the one body, looking straight down: its centre
# pixel is the body (state-coloured), not the floor or the sky
check "run one body" 0 "$run" run bolts --bodies 1 --frames 1 --workers 1 --record "$dir/one"
check "dump one" 0 "$view" --dump --frames 1:1 "$dir/one"
set -- $(grep "^frame 1 body 1 " "$dir/out")   # frame 1 body 1 state S pos X Y Z
x=$8 y=$9 z=${10}
if [ -z "$z" ]; then
    echo "FAIL: dump one: no body 1"; fail=1
else
    eye=$(echo "$z + 0.3" | bc)
    check "render from above" 0 "$view" --out "$dir" --size 64x64 --fov 30 --frames 1:1 \
        --eye "$x,$y,$eye" --look "$x,$y,$z" "$dir/one"
    check "png_check above" 0 "$png" "$dir/frame_00001.png" 64 64 $sky
    grep -q " body$" "$dir/out" || { echo "FAIL: centre pixel is not the body: $(cat "$dir/out")"; fail=1; }
    # and 0.5 m to the side of it, the floor
    check "render beside" 0 "$view" --out "$dir" --size 64x64 --fov 30 --frames 1:1 \
        --eye "$x,$(echo "$y + 0.5" | bc),$eye" --look "$x,$(echo "$y + 0.5" | bc),$z" "$dir/one"
    check "png_check beside" 0 "$png" "$dir/frame_00001.png" 64 64 $sky
    grep -q " grey$" "$dir/out" || { echo "FAIL: centre pixel is not the floor: $(cat "$dir/out")"; fail=1; }
fi

# a scene with walls as static boxes (examples/scenes/bin.scene): the
# default camera rises over them, so the parts are in view (the walls and
# the floor alone make a handful of colours; the parts' shading, dozens)
check "run bin.scene --record" 0 "$run" run examples/scenes/bin.scene --frames 5 --workers 1 \
    --record "$dir/bin"
check "render bin.scene" 0 "$view" --out "$dir/binpng" --size 96x72 --frames 5:5 "$dir/bin"
check "png_check bin.scene" 0 "$png" "$dir/binpng/frame_00005.png" 96 72 $sky
set -- $(cat "$dir/out")    # colours N nonsky F centre R G B CLASS
[ "${2:-0}" -gt 20 ] || { echo "FAIL: bin.scene: the walls hide the parts: $(cat "$dir/out")"; fail=1; }

# usage errors: exit 2, one line
for args in "" "--size 8x8 $dir/log" "--size 640 $dir/log" "--eye 1,2 $dir/log" \
    "--fov 0 $dir/log" "--every 0 $dir/log" "--frames 9:3 $dir/log" "--frobnicate $dir/log" \
    "$dir/log $dir/log"; do
    check "usage: $args" 2 "$view" $args
    one_line "usage: $args" "try --help"
done
check "--help" 0 "$view" --help
grep -q -- "--eye" "$dir/out" || { echo "FAIL: --help does not list --eye"; fail=1; }
check "--version" 0 "$view" --version
version=$(sed -n 's/^VERSION *:= *//p' "$(dirname "$0")/../Makefile")
grep -qx "simcluster-view $version" "$dir/out" || { echo "FAIL: --version: $(cat "$dir/out")"; fail=1; }
check "-h" 0 "$view" -h
grep -q -- "--out DIR" "$dir/out" || { echo "FAIL: -h does not list --out"; fail=1; }

# bad input: exit 1, one line naming the file (and the event)
check "missing log" 1 "$view" --out "$dir" "$dir/none"
one_line "missing log" "$dir/none"
size=$(wc -c <"$dir/log")
head -c $((size - 100)) "$dir/log" >"$dir/cut"
check "truncated log" 1 "$view" --out "$dir/png" "$dir/cut"
one_line "truncated log" "$dir/cut: event 34"
head -c 1000 /dev/zero >"$dir/zero"
check "not a log" 1 "$view" --out "$dir/png" "$dir/zero"
one_line "not a log" "$dir/zero: not a recording"
check "a scene file" 1 "$view" --out "$dir/png" examples/scenes/crates.scene
one_line "a scene file" "not a recording .*simcluster run FILE --record LOG"
check "a log without frames" 1 "$view" --out "$dir/png" --frames 100:200 "$dir/log"
check "--out not a directory" 1 "$view" --out "$dir/zero" "$dir/log"
one_line "--out not a directory" "zero: not a directory"
check "--out in a missing directory" 1 "$view" --out "$dir/no/such" "$dir/log"
one_line "--out in a missing directory" "no/such: No such file or directory"
# --out DIR/ that is not there yet: created, as the man page's example needs
check "--out a new directory" 0 "$view" --out "$dir/frames/" --every 10 --size 32x32 "$dir/log"
[ "$(ls "$dir/frames" | wc -l)" -eq 4 ] || { echo "FAIL: --out frames/: $(ls "$dir/frames")"; fail=1; }
if [ "$(id -u)" -ne 0 ]; then        # root writes anywhere
    mkdir "$dir/ro" && chmod 555 "$dir/ro"
    check "--out not writable" 1 "$view" --out "$dir/ro" "$dir/log"
    one_line "--out not writable" "ro: Permission denied"
fi
check "--mp4 without ffmpeg" 1 env PATH=/nonexistent "$view" --mp4 "$dir/v.mp4" "$dir/log"
one_line "--mp4 without ffmpeg" "ffmpeg"
# with ffmpeg (scripts/deps.sh video): the README's video command works
if command -v ffmpeg >/dev/null 2>&1; then
    check "--mp4" 0 "$view" --mp4 "$dir/v.mp4" --size 64x48 "$dir/log"
    [ "$(od -An -c -j4 -N4 "$dir/v.mp4" 2>/dev/null | tr -d ' ')" = ftyp ] ||
        { echo "FAIL: --mp4: not an MP4 file"; fail=1; }
else
    echo "skipped: --mp4 (no ffmpeg: sh scripts/deps.sh video)"
fi
# the optional packages are listed by scripts/deps.sh and named in the README
grep -q '^VIDEO_PKGS="ffmpeg"' scripts/deps.sh && grep -q "scripts/deps.sh video" README.md ||
    { echo "FAIL: ffmpeg is not in scripts/deps.sh video or the README"; fail=1; }

# live: the viewer subscribed while a run publishes (ttl=0: this host only)
# a port of its own: another checkout's tests on this host must not be heard
port=$((20000 + $(od -An -N2 -tu2 /dev/urandom | tr -d ' ') % 10000))
url="udpm://239.255.76.67:$port?ttl=0"
live() { # $1 = folder, then viewer options; the viewer runs in the background
    d=$1; shift
    mkdir -p "$d"
    "$view" --live "$url" --out "$d" --size 64x48 "$@" >"$dir/lout" 2>"$dir/lerr" &
    vpid=$!
    sleep 1                        # subscribed before anything is sent
}
live_done() { # $1 = what, $2 = expected status
    wait "$vpid"
    got=$?
    [ "$got" -eq "$2" ] || { echo "FAIL: $1: viewer exit $got, expected $2"; cat "$dir/lerr"; fail=1; }
}
live "$dir/live" --frames 5:40 --timeout 20
check "run --publish" 0 "$run" run bolts --bodies 3 --frames 60 --workers 1 --realtime --publish "$url"
live_done "live view" 0
n=$(ls "$dir/live" | grep -c '^frame_000[0-4][0-9].png$')
[ "$n" -ge 5 ] || { echo "FAIL: live view: $n frames"; ls "$dir/live"; cat "$dir/lerr"; fail=1; }
ls "$dir/live" | grep -qv '^frame_000\(0[5-9]\|[1-3][0-9]\|40\).png$' &&
    { echo "FAIL: live view: frames outside 5:40"; ls "$dir/live"; fail=1; }
last=$(ls "$dir/live" | tail -1)
check "png_check live" 0 "$png" "$dir/live/$last" 64 48 $sky
set -- $(cat "$dir/out")
[ "${2:-0}" -ge 8 ] || { echo "FAIL: live $last: only ${2:-0} colours"; fail=1; }
# lcm-logplayer replays a recorded log to the same channels
if command -v lcm-logplayer >/dev/null; then
    live "$dir/replay" --timeout 3
    lcm-logplayer -s 1 -l "$url" "$dir/log" >/dev/null 2>&1 ||
        { echo "FAIL: lcm-logplayer"; fail=1; }
    live_done "live view of lcm-logplayer" 0
    [ "$(ls "$dir/replay" | wc -l)" -ge 3 ] || { echo "FAIL: replay: $(ls "$dir/replay" | wc -l) frames"; fail=1; }
    # the summary accounts for every frame not drawn (the replay comes
    # faster than the viewer draws: it skips to the newest)
    set -- $(sed -n 's/.*: \([0-9]*\) frames drawn of \([0-9]*\) received.*/\1 \2/p' "$dir/lerr")
    if [ "${1:-0}" -lt "${2:-0}" ] && ! grep -q "replaced by a newer frame\|before their shapes came" "$dir/lerr"; then
        echo "FAIL: replay: frames not drawn and not said why: $(cat "$dir/lerr")"; fail=1
    fi
    # hostile messages on the channels: dropped and counted, no frame, exit 1
    python3 - "$dir/bad.log" <<'PY'
import struct, sys
ev = []
for i, (ch, data) in enumerate([(b"SC_STATE", b"\x00" * 7), (b"SC_STATE", b"\xff" * 200),
                                (b"SC_SHAPE", b"\x01" * 50),
                                (b"SC_STATE", b"\x00" * 24 + struct.pack(">i", 2**30))]):
    ev.append(struct.pack(">IqqII", 0xEDA1DA01, i, i * 1000, len(ch), len(data)) + ch + data)
open(sys.argv[1], "wb").write(b"".join(ev))
PY
    live "$dir/bad" --timeout 2
    lcm-logplayer -l "$url" "$dir/bad.log" >/dev/null 2>&1
    live_done "live view of hostile messages" 1
    # (a state overtaken by a newer one before it is drawn is skipped unread)
    grep -q "0 frames drawn of 3 received, [1-4] malformed messages dropped" "$dir/lerr" ||
        { echo "FAIL: hostile live messages not counted"; cat "$dir/lerr"; fail=1; }
fi
check "--live with a log" 2 "$view" --live "$url" "$dir/log"
check "--timeout without --live" 2 "$view" --timeout 1 "$dir/log"
check "--live, bad URL" 1 "$view" --live "udpm://999.1.1.1:7669" --out "$dir"
grep -q "cannot open udpm://999.1.1.1:7669: 999.1.1.1 is not an IPv4 multicast address" "$dir/err" ||
    { echo "FAIL: --live, bad URL: no error"; cat "$dir/err"; fail=1; }

[ "$fail" -eq 0 ] && echo "view: all checks passed"
exit "$fail"
