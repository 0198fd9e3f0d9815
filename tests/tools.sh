#!/bin/sh
# tests/tools.sh BUILD - the command-line tools as a user meets them: exit
# statuses, one-line errors, the files they write.
tool="$1/tools/simcluster"
atool=$(cd "$1/tools" && pwd)/simcluster   # for commands run in $dir
dir=$(mktemp -d) || exit 1
trap 'rm -rf "$dir"' EXIT
fail=0
. "$(dirname "$0")/cli_lib.sh"
check "keygen" 0 "$tool" keygen "$dir/k"
[ "$(stat -c %a "$dir/k")" = 600 ] || { echo "FAIL: key mode $(stat -c %a "$dir/k")"; fail=1; }
grep -Eqx '[0-9a-f]{64}' "$dir/k" || { echo "FAIL: key is not 64 hex digits"; fail=1; }
[ "$(wc -c <"$dir/k")" -eq 65 ] || { echo "FAIL: key file size"; fail=1; }
cp "$dir/k" "$dir/k0"
check "keygen onto an existing file" 1 "$tool" keygen "$dir/k"
cmp -s "$dir/k" "$dir/k0" || { echo "FAIL: an existing key was changed"; fail=1; }
[ "$(wc -l <"$dir/err")" -eq 1 ] || { echo "FAIL: error is not one line"; fail=1; }
grep -q "exists" "$dir/err" || { echo "FAIL: error does not say the file exists"; fail=1; }
check "two keys differ" 0 "$tool" keygen "$dir/k2"
cmp -s "$dir/k" "$dir/k2" && { echo "FAIL: two keys are equal"; fail=1; }
check "keygen into a missing directory" 1 "$tool" keygen "$dir/no/such/k"
check "keygen without a file" 2 "$tool" keygen
check "a mistyped scene" 2 "$tool" run bolt
one_line "a mistyped scene" "built-in scenes are bolts, bin, spheres, stack, pyramid and wall"
check "--bodies for spheres" 2 "$tool" run spheres --bodies 5 --frames 1
one_line "--bodies for spheres" "for the bolts, bin and structure scenes"
check "--seed for stack" 2 "$tool" run stack --seed 3 --frames 1
one_line "--seed for stack" "a structure has no randomness"
# a stack of 30 cubes: one island solved whole by the active set, exactly,
# in one factorisation a solve, standing still; block Gauss-Seidel on the
# same stack iterates, tens of sweeps a solve, only to its tolerance
check "run stack" 0 "$tool" run stack --bodies 30 --frames 100 --json
python3 - "$dir/out" <<'PY' || { echo "FAIL: run stack: not solved whole"; cat "$dir/out"; fail=1; }
import json, sys
d = json.load(open(sys.argv[1])); r = d["solver"]; a = r["active_set"]
sys.exit(not (d["bodies"] == 31 and r["island_method"] == "active-set" and a["solves"] > 0
              and a["fallbacks"] == 0 and a["iterations_max"] <= 2 and r["unconverged"] == 0
              and r["max_residual"] < 1e-9 and d["max_penetration_m"] < 1e-3))
PY
check "run stack --island-method block-gs" 0 "$tool" run stack --bodies 30 --frames 100 --json --island-method block-gs
python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))["solver"]; sys.exit(not (r["island_method"] == "block-gs" and r["active_set"]["solves"] == 0 and r["max_sweeps"] > 10 and 1 <= r["sweeps_mean"] <= r["max_sweeps"] and r["max_outer_residual"] > 1e-6))' "$dir/out" ||
    { echo "FAIL: run stack --island-method block-gs"; cat "$dir/out"; fail=1; }
# a stack of 100 cubes by subdomains: one island of several parts, their
# exchanges counted
check "run stack --island-method subdomains" 0 "$tool" run stack --bodies 100 --frames 20 \
    --json --island-method subdomains
python3 - "$dir/out" <<'PY' || { echo "FAIL: run stack --island-method subdomains"; cat "$dir/out"; fail=1; }
import json, sys
r = json.load(open(sys.argv[1]))["solver"]; a = r["active_set"]
sys.exit(not (r["island_method"] == "subdomains" and a["solves"] > 0 and a["parts_max"] > 1
              and a["interface_max"] > 0 and a["exchanges"] > 0 and a["exchange_bytes"] > 0))
PY
check "run --island-method sideways" 2 "$tool" run stack --island-method sideways
one_line "run --island-method sideways" "--island-method takes active-set, block-gs or subdomains"
check "--bodies for bin" 0 "$tool" run bin --bodies 8 --frames 1
# plain make builds the library, tools, daemon and examples
goal=$(make -C "$(dirname "$0")/.." -pn 2>/dev/null | sed -n 's/^\.DEFAULT_GOAL := //p' | tail -n 1)
[ "$goal" = all ] || { echo "FAIL: plain make builds '$goal', not all"; fail=1; }
check "no command" 2 "$tool"
check "unknown command" 2 "$tool" frobnicate
check "--help" 0 "$tool" --help
grep -q keygen "$dir/out" || { echo "FAIL: --help does not list keygen"; fail=1; }
for c in run profile lcp; do
    grep -q "$c" "$dir/out" || { echo "FAIL: --help does not list $c"; fail=1; }
done
# --version (the Makefile's VERSION) and COMMAND --help / -h: to stdout,
# status 0; keygen --help writes no key file named --help
version=$(sed -n 's/^VERSION *:= *//p' "$(dirname "$0")/../Makefile")
for c in "" run profile lcp keygen; do
    check "$c --version" 0 "$tool" $c --version
    grep -qx "simcluster $version" "$dir/out" || { echo "FAIL: $c --version: $(cat "$dir/out")"; fail=1; }
done
for c in run profile lcp keygen; do
    for h in --help -h; do
        (cd "$dir" && "$atool" $c $h >"$dir/out" 2>"$dir/err")
        rc=$?
        [ "$rc" -eq 0 ] && [ ! -s "$dir/err" ] && grep -q "^usage: simcluster $c " "$dir/out" ||
            { echo "FAIL: $c $h: exit $rc"; cat "$dir/out" "$dir/err"; fail=1; }
        [ -e "$dir/$h" ] && { echo "FAIL: $c $h wrote a file $h"; rm -f "$dir/$h"; fail=1; }
    done
done
grep -q -- "--record" "$dir/out" && { echo "FAIL: keygen -h lists run's options"; fail=1; }
check "run --help" 0 "$tool" run --help
grep -q -- "--render DIR" "$dir/out" && grep -q -- "--wait-daemons" "$dir/out" ||
    { echo "FAIL: run --help: options"; cat "$dir/out"; fail=1; }
check "profile --help" 0 "$tool" profile --help
grep -q -- "--render" "$dir/out" && { echo "FAIL: profile --help lists run's --render"; fail=1; }
check "keygen, an unknown option" 2 "$tool" keygen --frobnicate
one_line "keygen, an unknown option" "keygen -- FILE"
(cd "$dir" && "$atool" keygen -- -k >/dev/null 2>&1) && [ -s "$dir/-k" ] ||
    { echo "FAIL: keygen -- -k wrote no file -k"; fail=1; }
check "lcp, an unknown option" 2 "$tool" lcp --frobnicate

# run: a short drop, text and JSON; the same seed gives the same state
check "run bolts" 0 "$tool" run bolts --bodies 12 --frames 60 --workers 2
grep -q "^bolts: 13 bodies" "$dir/out" || { echo "FAIL: run: no report"; cat "$dir/out"; fail=1; }
h1=$(sed -n 's/.*state hash //p' "$dir/out")
check "run bolts, one worker" 0 "$tool" run bolts --bodies 12 --frames 60 --workers 1
h2=$(sed -n 's/.*state hash //p' "$dir/out")
[ -n "$h1" ] && [ "$h1" = "$h2" ] || { echo "FAIL: run: hash $h1 with 2 workers, $h2 with 1"; fail=1; }
[ -s "$dir/err" ] && { echo "FAIL: run: output on stderr when it is not a terminal"; cat "$dir/err"; fail=1; }
check "run --json" 0 "$tool" run bolts --bodies 5 --until-rest --json
grep -q '"at_rest": true' "$dir/out" || { echo "FAIL: run --json: not at rest"; cat "$dir/out"; fail=1; }
python3 -c 'import json,sys; json.load(open(sys.argv[1]))' "$dir/out" 2>/dev/null ||
    { command -v python3 >/dev/null && { echo "FAIL: run --json is not JSON"; fail=1; }; }
grep -q '"frames_over_budget": [0-9]*, "max_frame_s": 0\.[0-9]*' "$dir/out" ||
    { echo "FAIL: run --json: no frames_over_budget, max_frame_s"; cat "$dir/out"; fail=1; }
# bodies placed inside each other: a warning on stderr and the count in the
# report (27 coincident spheres: 351 pairs), not a silent run
cat >"$dir/heap.scene" <<'EOF'
shape floor plane 0 0 1 0
shape ball sphere 0.1
body floor
body ball mass 1 pos 0 0 0.5 grid 3 3 3 0 0 0
EOF
check "run, bodies placed inside each other" 0 "$tool" run "$dir/heap.scene" --frames 20 --json
one_line "run, bodies inside each other" "warning: 351 body pairs overlap"
grep -q '"initial_overlaps": 351' "$dir/out" ||
    { echo "FAIL: run --json: no initial_overlaps 351"; cat "$dir/out"; fail=1; }
# the heap is one island of 351 contacts: split into blocks by default,
# one exact LCP with --island-split 0; both say so, with the residuals
python3 - "$dir/out" <<'PY' || { echo "FAIL: run --json: solver figures of a split heap"; cat "$dir/out"; fail=1; }
import json, sys
r = json.load(open(sys.argv[1]))["solver"]
ok = (r["island_split"] == 16 and r["split"] > 0 and (r["blocks"] > 0 or r["active_set"]["solves"] > 0)
      and r["solves"] >= r["split"]
      and r["max_outer_residual"] >= 0 and r["substeps"] >= 20 and r["nan_islands"] == 0 and r["inelastic_islands"] >= 0
      and 0 <= r["blocks_shared"] <= r["blocks"] and 0 <= r["energy_refused"] <= r["staggered_fallbacks"]
      and r["restitution_scaled"] >= 0 and r["guessed"] >= 0)
sys.exit(not ok)
PY
check "run --island-split 0" 0 "$tool" run "$dir/heap.scene" --frames 5 --island-split 0
grep -q "split into blocks 0," "$dir/out" || { echo "FAIL: --island-split 0 split"; cat "$dir/out"; fail=1; }
grep -q "^  LCP residual at most [0-9.e+-]* m/s (exact)" "$dir/out" ||
    { echo "FAIL: run: no LCP residual line"; cat "$dir/out"; fail=1; }
grep -q "^  fallbacks: staggered friction [0-9]* ([0-9]* of them answers refused for adding energy), blocks after staggered [0-9]*, projected Gauss-Seidel blocks [0-9]*, non-finite islands 0, inelastic re-solves [0-9]*, restitution scaled down [0-9]*$" "$dir/out" ||
    { echo "FAIL: run: no fallbacks line"; cat "$dir/out"; fail=1; }
# the dense pile: islands split into blocks, the same bits on 1 and 3 threads
check "run bin, one worker" 0 "$tool" run bin --bodies 40 --frames 120 --workers 1 --json
hb1=$(python3 -c 'import json,sys; r = json.load(open(sys.argv[1])); print(r["hash"] if r["solver"]["split"] > 0 and r["error"] is None else "")' "$dir/out")
check "run bin, three workers" 0 "$tool" run bin --bodies 40 --frames 120 --workers 3 --json
hb3=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["hash"])' "$dir/out")
[ -n "$hb1" ] && [ "$hb1" = "$hb3" ] || { echo "FAIL: run bin: hash '$hb1' (split) on 1 worker, $hb3 on 3"; fail=1; }
# the time of impact: local (run's default) and world (profile's), the same bits on 1 and 3
# threads in local mode too, back-ups and speculative contacts reported
check "run bin --toi local, one worker" 0 "$tool" run bin --bodies 40 --frames 60 --workers 1 --toi local --json
hl1=$(python3 -c 'import json,sys; r = json.load(open(sys.argv[1]))["toi"]; print(json.load(open(sys.argv[1]))["hash"] if r["mode"] == "local" and r["speculative_contacts"] > 0 and r["max_frame_backups"] >= 0 else "")' "$dir/out")
check "run bin --toi local, three workers" 0 "$tool" run bin --bodies 40 --frames 60 --workers 3 --toi local --json
hl3=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["hash"])' "$dir/out")
[ -n "$hl1" ] && [ "$hl1" = "$hl3" ] || { echo "FAIL: run bin --toi local: hash '$hl1' on 1 worker, $hl3 on 3"; fail=1; }
check "run --toi world" 0 "$tool" run bolts --bodies 12 --frames 40 --toi world
grep -q "^  time of impact (world): back-ups [0-9.]* a frame (most [0-9]*), speculative contacts 0$" "$dir/out" ||
    { echo "FAIL: run: no time of impact line"; cat "$dir/out"; fail=1; }
check "run, local by default" 0 "$tool" run bolts --bodies 12 --frames 40
grep -q "^  time of impact (local): back-ups [0-9.]* a frame (most [0-9]*), speculative contacts [0-9]*$" "$dir/out" ||
    { echo "FAIL: run: not local by default"; cat "$dir/out"; fail=1; }
check "profile, world-wide by default" 0 "$tool" profile bolts --bodies 12 --frames 20 --json
python3 -c 'import json,sys; sys.exit(json.load(open(sys.argv[1]))["toi_mode"] != "world")' "$dir/out" ||
    { echo "FAIL: profile: not the paper's world-wide mode"; cat "$dir/out"; fail=1; }
check "run --toi sideways" 2 "$tool" run bolts --toi sideways
one_line "run --toi sideways" "--toi takes world or local"
check "run --island-split -1" 2 "$tool" run bolts --island-split -1
one_line "run --island-split -1" "--island-split takes 0..1000000"
check "run --min-gain 0" 2 "$tool" run bolts --min-gain 0
one_line "run --min-gain 0" "--min-gain takes round trips in (0, 1000]"
check "run --min-gain -1" 0 "$tool" run bolts --bodies 5 --frames 5 --min-gain -1
check "run, bodies not inside each other" 0 "$tool" run bolts --bodies 12 --frames 20
[ -s "$dir/err" ] && { echo "FAIL: run bolts: stderr not empty"; cat "$dir/err"; fail=1; }
grep -q "overlapping" "$dir/out" && { echo "FAIL: run bolts: overlaps reported"; fail=1; }
check "run --wait-daemons without --cluster" 2 "$tool" run bolts --wait-daemons 1
one_line "run --wait-daemons without --cluster" "needs --cluster"
check "run without a scene" 2 "$tool" run
check "run, a scene file that is not there" 1 "$tool" run cubes.scene
one_line "run, missing scene file" "cubes.scene: No such file or directory"
check "run, bad --bodies" 2 "$tool" run bolts --bodies 0
check "run, unknown option" 2 "$tool" run bolts --frobnicate
[ "$(wc -l <"$dir/err")" -eq 1 ] || { echo "FAIL: run: error is not one line"; fail=1; }
check "run, --key without --cluster" 2 "$tool" run bolts --key "$dir/k"
check "run, unopenable cluster URL" 1 "$tool" run bolts --cluster "udpm://999.1.1.1:7667"
grep -q "^simcluster: run: --cluster udpm://999.1.1.1:7667: 999.1.1.1 is not an IPv4 multicast address$" "$dir/err" ||
    { echo "FAIL: run, unopenable cluster URL: the URL is not named"; cat "$dir/err"; fail=1; }
# only udpm:// (the cluster's own transport), other LCM providers refused by name
check "run, mpudpm:// URL" 1 "$tool" run bolts --cluster "mpudpm://239.255.76.67:7667"
one_line "run, mpudpm:// URL" "^simcluster: run: --cluster mpudpm://239.255.76.67:7667: only LCM's udpm://.* URLs are supported (not this provider)$"
# which of key file and URL could not be opened, named
curl="udpm://239.255.76.67:7667?ttl=0"
check "run, missing key file" 1 "$tool" run bolts --frames 1 --cluster "$curl" --key "$dir/nokey"
one_line "run, missing key file" "^simcluster: run: --key $dir/nokey: No such file or directory$"
cp "$dir/k" "$dir/k644" && chmod 644 "$dir/k644"
check "run, key file mode 0644" 1 "$tool" run bolts --frames 1 --cluster "$curl" --key "$dir/k644"
one_line "run, key file mode 0644" "^simcluster: run: --key $dir/k644: .*0600$"
printf 'not a key\n' >"$dir/badkey" && chmod 600 "$dir/badkey"
check "run, malformed key file" 1 "$tool" run bolts --frames 1 --cluster "$curl" --key "$dir/badkey"
one_line "run, malformed key file" "^simcluster: run: --key $dir/badkey: not a cluster key"

# scene files: the examples run; errors name file, line and column
scenes="$(dirname "$0")/../examples/scenes"
for s in "$scenes"/*.scene; do
    check "run $(basename "$s")" 0 "$tool" run "$s" --frames 30 --workers 2
    grep -q "bodies, 30 frames" "$dir/out" || { echo "FAIL: run $s: no report"; cat "$dir/out"; fail=1; }
done
# the dense parts bin (the loop above ran it): floor, four walls, 64 parts
check "run bin.scene, whole" 0 "$tool" run "$scenes/bin.scene" --frames 5 --workers 1
grep -q "bin.scene: 69 bodies, 5 frames" "$dir/out" ||
    { echo "FAIL: bin.scene: not 69 bodies"; cat "$dir/out"; fail=1; }
printf 'shape ball sphere 0.1\nbody ball pos 1 2\n' >"$dir/bad.scene"
check "run, bad scene file" 1 "$tool" run "$dir/bad.scene"
one_line "run, bad scene file" "bad.scene:2:18: missing position (m)"
check "run, scene file with --bodies" 2 "$tool" run "$scenes/bolts.scene" --bodies 3
printf 'shape floor plane 0 0 1 0\nshape b box 0.1 0.1 0.1\nbody floor\nbody b density 500 pos 0 0 0.2\n' \
    >"$dir/a \"quoted\" name.scene"
check "run --json, a scene file with quotes in its name" 0 "$tool" run "$dir/a \"quoted\" name.scene" \
    --frames 20 --json --workers 1
grep -q '"bodies": 2, "seed": null' "$dir/out" || { echo "FAIL: scene --json"; cat "$dir/out"; fail=1; }
python3 -c 'import json,sys; json.load(open(sys.argv[1]))' "$dir/out" 2>/dev/null ||
    { command -v python3 >/dev/null && { echo "FAIL: scene --json is not JSON"; cat "$dir/out"; fail=1; }; }
check "profile a scene file" 0 "$tool" profile "$scenes/crates.scene" --frames 20
grep -q "Dantzig" "$dir/out" || { echo "FAIL: profile of a scene file"; fail=1; }

# --realtime: 20 frames take at least 0.2 s; --publish on a bad URL fails
check "run --realtime" 0 "$tool" run bolts --bodies 3 --frames 20 --realtime --json
awk -F'"wall_s": ' '{ split($2, a, ","); exit !(a[1] >= 0.195) }' "$dir/out" ||
    { echo "FAIL: --realtime ran faster than simulated time"; cat "$dir/out"; fail=1; }
check "run --publish, bad URL" 1 "$tool" run bolts --bodies 3 --frames 2 --publish "udpm://999.1.1.1:7668"
one_line "run --publish, bad URL" "^simcluster: run: --publish udpm://999.1.1.1:7668: 999.1.1.1 is not an IPv4 multicast address$"
check "profile --publish" 2 "$tool" profile spheres --publish "udpm://239.255.76.67:7668?ttl=0"

# run --render: every frame drawn by simcluster-view, the report alone on stdout
# (ASan: Mesa's own never-freed framebuffer list is not our leak)
LSAN_OPTIONS="suppressions=$PWD/tests/lsan_osmesa.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export LSAN_OPTIONS
mkdir "$dir/png"
check "run --render" 0 "$tool" run bolts --bodies 3 --frames 4 --workers 1 --render "$dir/png" --json
[ "$(ls "$dir/png" | grep -c '^frame_0000[0-4].png$')" -eq 5 ] ||
    { echo "FAIL: run --render: frames"; ls "$dir/png"; fail=1; }
[ "$(wc -l <"$dir/out")" -eq 1 ] || { echo "FAIL: run --render --json: stdout"; cat "$dir/out"; fail=1; }
check "run --render into a missing directory" 1 "$tool" run bolts --bodies 3 --frames 2 --render "$dir/no/such"
check "profile --render" 2 "$tool" profile spheres --render "$dir/png"

# SIGINT, SIGTERM: the run stops after the current frame, reports the frames
# so far (marked interrupted; JSON stays JSON), exits 128 + the signal, and
# its --record log ends on a whole event (simcluster-view reads all of it).
# A background job of sh starts with SIGINT ignored; run sets its handler.
view="$1/tools/simcluster-view"
stop_run() { # $1 = signal, then the run's arguments; sets $rc
    sig=$1; shift
    rm -f "$dir/int.log"
    "$tool" run "$@" --record "$dir/int.log" >"$dir/out" 2>"$dir/err" &
    rp=$!
    i=0     # until the log holds some frames (its shapes and frame 0: ~3 kB)
    while [ "$(stat -c %s "$dir/int.log" 2>/dev/null || echo 0)" -lt 20000 ] && [ "$i" -lt 100 ]; do
        i=$((i + 1)); sleep 0.1
    done
    kill -"$sig" "$rp"
    i=0     # it stops within 10 s (a frame is milliseconds)
    while kill -0 "$rp" 2>/dev/null && [ "$i" -lt 100 ]; do i=$((i + 1)); sleep 0.1; done
    kill -0 "$rp" 2>/dev/null && { echo "FAIL: SIG$sig: still running after 10 s"; kill -9 "$rp"; fail=1; }
    wait "$rp"
    rc=$?
}
# the report against the log: the log's last frame is the report's count
interrupted_log() { # $1 = what, $2 = the report's frame count
    if "$view" --dump "$dir/int.log" >"$dir/dump" 2>"$dir/err"; then
        last=$(awk '$1 == "frame" && $3 == "body" && $4 == 0 { f = $2 } END { print f }' "$dir/dump")
        [ -n "$2" ] && [ "$last" = "$2" ] ||
            { echo "FAIL: $1: log ends at frame $last, report says '$2'"; fail=1; }
    else
        echo "FAIL: $1: the log is not whole"; cat "$dir/err"; fail=1
    fi
}
stop_run INT bolts --bodies 20 --frames 1000000 --realtime --workers 1 --json
[ "$rc" -eq 130 ] || { echo "FAIL: SIGINT: exit $rc, expected 130"; cat "$dir/err"; fail=1; }
python3 -c 'import json,sys; r = json.load(open(sys.argv[1])); sys.exit(not (r["interrupted"] == "SIGINT" and r["frames"] > 0 and r["error"] is None))' "$dir/out" ||
    { echo "FAIL: SIGINT: the JSON report"; cat "$dir/out"; fail=1; }
frames=$(sed -n 's/.*"frames": \([0-9]*\),.*/\1/p' "$dir/out")
interrupted_log "SIGINT" "$frames"
stop_run TERM bolts --bodies 20 --frames 1000000 --realtime --workers 1
[ "$rc" -eq 143 ] || { echo "FAIL: SIGTERM: exit $rc, expected 143"; cat "$dir/err"; fail=1; }
grep -q "^  interrupted by SIGTERM after frame [1-9][0-9]*$" "$dir/out" && grep -q "state hash" "$dir/out" ||
    { echo "FAIL: SIGTERM: the report"; cat "$dir/out"; fail=1; }
frames=$(sed -n 's/.* \([0-9]*\) frames of .*/\1/p' "$dir/out")
interrupted_log "SIGTERM" "$frames"
# a --render folder that cannot be used stops the run before its first frame
: >"$dir/afile"
check "run --render into a file" 1 "$tool" run bolts --frames 100000 --render "$dir/afile"
one_line "run --render into a file" "^simcluster: run: --render $dir/afile: not a directory$"
[ -s "$dir/out" ] && { echo "FAIL: run --render into a file: ran"; cat "$dir/out"; fail=1; }
check "run --render in a missing directory" 1 "$tool" run bolts --frames 100000 --render "$dir/no/such"
one_line "run --render in a missing directory" "no/such: No such file or directory$"
if [ "$(id -u)" -ne 0 ]; then        # root writes anywhere
    mkdir "$dir/ro" && chmod 555 "$dir/ro"
    check "run --render, not writable" 1 "$tool" run bolts --frames 100000 --render "$dir/ro"
    one_line "run --render, not writable" "ro: Permission denied$"
fi

# profile: the Table 1 rows
check "profile" 0 "$tool" profile spheres --frames 50
grep -q "Dantzig" "$dir/out" && grep -q "41.48" "$dir/out" || { echo "FAIL: profile rows"; fail=1; }

# profile --chart: where the time goes as a PNG (gnuplot); without gnuplot
# on the PATH a one-line error that says how to get it
check "run --chart" 2 "$tool" run spheres --chart "$dir/c.png"
one_line "run --chart" "is an option of profile"
check "profile --chart, no gnuplot" 1 env PATH=/nonexistent "$atool" profile spheres --frames 20 \
    --chart "$dir/c.png"
one_line "profile --chart, no gnuplot" "needs gnuplot (sh scripts/deps.sh bench"
if command -v gnuplot >/dev/null 2>&1; then
    check "profile --chart" 0 "$tool" profile spheres --frames 50 --chart "$dir/c.png"
    # a PNG of 900 x 480: the signature, then IHDR's width and height
    sig=$(od -An -tx1 -N8 "$dir/c.png" | tr -d ' \n')
    wh=$(od -An -tu1 -j16 -N8 "$dir/c.png" | tr -s ' ' | sed 's/^ //')
    [ "$sig" = 89504e470d0a1a0a ] && [ "$wh" = "0 0 3 132 0 0 1 224" ] ||
        { echo "FAIL: profile --chart: not a 900x480 PNG ($sig; $wh)"; fail=1; }
    check "profile --chart into a missing folder" 1 "$tool" profile spheres --frames 5 \
        --chart "$dir/no/c.png"
    one_line "profile --chart, missing folder" "no/c.png: No such file or directory"
else
    echo "tools: gnuplot not installed: profile --chart checked without it only"
fi

# lcp: a known solution, and errors that name the line and column
printf '# 2x2\n2\n2 1\n1 2\n-1 -1\n' >"$dir/lcp"
check "lcp" 0 "$tool" lcp "$dir/lcp"
grep -q "^0 0.3333333333333333" "$dir/out" || { echo "FAIL: lcp: wrong z"; cat "$dir/out"; fail=1; }
printf '2\n2 1\n1 x\n-1 -1\n' >"$dir/lcp"
check "lcp, bad number" 1 "$tool" lcp "$dir/lcp"
grep -q ":3:3: not a finite number" "$dir/err" || { echo "FAIL: lcp: position"; cat "$dir/err"; fail=1; }
printf '2\n2 1\n1 2\n-1\n' >"$dir/lcp"
check "lcp, short file" 1 "$tool" lcp "$dir/lcp"
grep -q "ends inside q" "$dir/err" || { echo "FAIL: lcp: short file"; cat "$dir/err"; fail=1; }
check "lcp, missing file" 1 "$tool" lcp "$dir/none"

[ "$fail" -eq 0 ] && echo "tools: all checks passed"
exit "$fail"
