#!/bin/sh
# tests/top.sh BUILD - simcluster-top(1) as an operator meets it: exit
# statuses and one-line errors, then a real simclusterd on a private
# multicast port: --once shows its row (node, host, cores, busy, a rate
# from two heartbeats) and a footer of one daemon; with another key it
# shows no row and counts the heartbeats it dropped; the live mode prints
# a table per interval and stops with status 0 on SIGTERM and SIGINT.
top="$1/tools/simcluster-top"
daemon="$1/daemon/simclusterd"
tool="$1/tools/simcluster"
inject="$1/tests/cluster_inject"
[ -x "$inject" ] || inject="build/tests/cluster_inject"
dir=$(mktemp -d) || exit 1
pid=""
live=""
trap '[ -n "$pid" ] && kill -9 "$pid" 2>/dev/null; [ -n "$live" ] && kill -9 "$live" 2>/dev/null
      rm -rf "$dir"' EXIT
trap 'exit 1' INT TERM HUP
fail=0
. "$(dirname "$0")/cli_lib.sh"
# The live top ($live) stops with status 0 on signal $1 within 5 s.
stop_live() {
    kill -"$1" "$live" 2>/dev/null
    i=0
    while kill -0 "$live" 2>/dev/null && [ "$i" -lt 50 ]; do i=$((i + 1)); sleep 0.1; done
    if kill -0 "$live" 2>/dev/null; then
        kill -9 "$live"; wait "$live"; echo "FAIL: live mode: still running 5 s after SIG$1"; fail=1
    else
        wait "$live"; rc=$?
        [ "$rc" -eq 0 ] || { echo "FAIL: live mode: exit $rc after SIG$1, expected 0"; fail=1; }
    fi
    live=""
}

check "--version" 0 "$top" --version
version=$(sed -n 's/^VERSION *:= *//p' "$(dirname "$0")/../Makefile")
grep -qx "simcluster-top $version" "$dir/out" || { echo "FAIL: --version says $(cat "$dir/out")"; fail=1; }
check "--help" 0 "$top" --help
for o in --url --key --insecure --once --wait --interval --json; do
    grep -q -- "$o" "$dir/out" || { echo "FAIL: --help does not list $o"; fail=1; }
done
check "unknown option" 2 "$top" --frobnicate
one_line "unknown option" "try --help"
check "missing value" 2 "$top" --insecure --once --wait
one_line "missing value" "--wait needs a value"
check "--interval 0" 2 "$top" --insecure --interval 0
one_line "--interval 0" "--interval"
check "--wait x" 2 "$top" --insecure --once --wait x
one_line "--wait x" "--wait"
check "--wait without --once" 2 "$top" --insecure --wait 1
one_line "--wait without --once" "--once"
check "--key and --insecure" 2 "$top" --key "$dir/k" --insecure
one_line "--key and --insecure" "exclude each other"
check "an argument" 2 "$top" --insecure extra
one_line "an argument" "extra"
check "no key, no --insecure" 1 "$top" --once
one_line "no key" "simcluster keygen"
check "missing key file" 1 "$top" --once --key "$dir/nokey"
one_line "missing key file" "nokey"
check "keygen" 0 "$tool" keygen "$dir/k"
check "keygen, another key" 0 "$tool" keygen "$dir/other"
cp "$dir/k" "$dir/k644" && chmod 644 "$dir/k644"
check "key file mode 0644" 1 "$top" --once --key "$dir/k644"
one_line "key file mode 0644" "k644.*0600"
check "unopenable URL" 1 "$top" --once --key "$dir/k" --url "udpm://999.1.1.1:7667"
one_line "unopenable URL" "cannot listen on udpm://999.1.1.1:7667"

# A real daemon on a port of its own (ttl=0: this host only); as root it
# reads its key, then switches to nobody. -c: no /etc config of this host.
port=$((20000 + $(od -An -N2 -tu2 /dev/urandom | tr -d ' ') % 10000))
url="udpm://239.255.76.67:$port?ttl=0"
: >"$dir/empty.conf"
: >"$dir/log"
"$daemon" -c "$dir/empty.conf" --url "$url" --key "$dir/k" --threads 1 --node-id 4660 \
    --heartbeat 0.1 2>"$dir/log" &
pid=$!
host=$(uname -n | cut -c 1-24)
if wait_log "serving"; then
    check "--once" 0 "$top" --once --url "$url" --key "$dir/k"
    [ -s "$dir/err" ] && { echo "FAIL: --once: output on stderr"; cat "$dir/err"; fail=1; }
    # node host cores units/s/core idle% busy units/s seen-s-ago
    row=$(awk '$1 == "0000000000001234"' "$dir/out")
    set -- $row
    if [ "$#" -ne 8 ]; then
        echo "FAIL: --once: no row of 8 columns for node 0000000000001234"; cat "$dir/out"; fail=1
    else
        [ "$2" = "$host" ] || { echo "FAIL: --once: host '$2', expected '$host'"; fail=1; }
        [ "$3" = 1 ] || { echo "FAIL: --once: cores $3, expected 1"; fail=1; }
        case $6 in yes|no) ;; *) echo "FAIL: --once: busy column '$6'"; fail=1 ;; esac
        # no unit was sent: two heartbeats or more give a rate of 0
        [ "$7" = 0.0 ] || { echo "FAIL: --once: units/s '$7', expected 0.0"; fail=1; }
        awk -v s="$8" 'BEGIN { exit !(s >= 0 && s < 1) }' ||
            { echo "FAIL: --once: last seen $8 s ago"; fail=1; }
    fi
    head -n 1 "$dir/out" | grep -q "^node  *host  *cores  *units/s/core  *idle%  *busy  *units/s  *seen-s-ago$" ||
        { echo "FAIL: --once: header"; cat "$dir/out"; fail=1; }
    tail -n 1 "$dir/out" | grep -q "^1 daemon, [01] busy, 1 core, .*; dropped 0 format, 0 auth, 0 replay, 0 stale, 0 net, 0 kernel$" ||
        { echo "FAIL: --once: footer"; cat "$dir/out"; fail=1; }
    [ "$(wc -l <"$dir/out")" -eq 3 ] || { echo "FAIL: --once: not 3 lines"; cat "$dir/out"; fail=1; }
    grep -q "$(printf '\033')" "$dir/out" && { echo "FAIL: --once: escape codes"; fail=1; }

    # --json: the same table as one JSON object (units in the key names)
    check "--once --json" 0 "$top" --once --json --url "$url" --key "$dir/k"
    [ "$(wc -l <"$dir/out")" -eq 1 ] || { echo "FAIL: --once --json: not one line"; cat "$dir/out"; fail=1; }
    python3 - "$dir/out" "$host" "$url" <<'EOF' || { echo "FAIL: --once --json"; cat "$dir/out"; fail=1; }
import json, sys
t = json.load(open(sys.argv[1]))
d = t["daemons"]
assert t["url"] == sys.argv[3], t["url"]
assert len(d) == 1 and t["daemons_total"] == 1 and t["silent"] == 0, t
d = d[0]
assert d["node"] == "0000000000001234" and d["host"] == sys.argv[2] and d["cores"] == 1, d
assert d["busy"] in (True, False) and d["silent"] is False, d
assert d["units_per_s"] == 0 and 0 <= d["seen_s_ago"] < 1, d     # no unit was sent
assert d["units_per_s_per_core"] > 0 and 0 <= d["idle_percent"] <= 100, d
assert t["cores"] == 1 and t["dropped"] == {"format": 0, "auth": 0, "replay": 0, "stale": 0,
                                           "net": 0, "kernel": 0}, t
EOF
    "$top" --json --url "$url" --key "$dir/k" --interval 0.2 >"$dir/live" 2>"$dir/err" &
    live=$!
    sleep 1.2
    stop_live TERM
    python3 -c 'import json, sys
lines = open(sys.argv[1]).read().splitlines()
assert len(lines) >= 3, len(lines)
for l in lines:
    assert json.loads(l)["daemons_total"] == 1' "$dir/live" ||
        { echo "FAIL: live --json: not one object per line per interval"; cat "$dir/live"; fail=1; }

    # another key: every heartbeat fails the MAC check
    check "--once, wrong key" 0 "$top" --once --wait 1 --url "$url" --key "$dir/other"
    grep -Eq '^[0-9a-f]{16} ' "$dir/out" && { echo "FAIL: wrong key: a row"; cat "$dir/out"; fail=1; }
    auth=$(sed -n 's/^0 daemons, .*; dropped 0 format, \([0-9]*\) auth, 0 replay, 0 stale, 0 net, 0 kernel$/\1/p' "$dir/out")
    [ "${auth:-0}" -gt 0 ] || { echo "FAIL: wrong key: no dropped auth count"; cat "$dir/out"; fail=1; }

    # live, not on a terminal: a table per interval, blank lines between
    "$top" --url "$url" --key "$dir/k" --interval 0.2 >"$dir/live" 2>"$dir/err" &
    live=$!
    sleep 1.5
    stop_live TERM
    n=$(grep -c "^1 daemon, " "$dir/live")
    [ "$n" -ge 3 ] || { echo "FAIL: live mode: $n tables in 1.5 s"; cat "$dir/live"; fail=1; }
    [ "$(grep -c '^$' "$dir/live")" -eq $((n - 1)) ] ||
        { echo "FAIL: live mode: tables not separated by one blank line"; cat "$dir/live"; fail=1; }
    grep -q "$(printf '\033')" "$dir/live" && { echo "FAIL: live mode: escape codes"; fail=1; }
    # hostile LCM fragments on SC_ANNOUNCE (LCM 1.3.1 died of each): a
    # second fragment at offset 0xFFFFFFF0, 256 MB and 4 GB claims; top
    # lives, and counts them in its net column
    if [ -x "$inject" ]; then
        "$top" --url "$url" --key "$dir/k" --interval 0.2 >"$dir/live" 2>"$dir/err" &
        live=$!
        sleep 0.3
        for m in frag-wrap frag-huge frag-4g; do
            "$inject" --url "$url" --key "$dir/k" --channel SC_ANNOUNCE --mode "$m" \
                --count 10 --pace-us 0 >/dev/null || { echo "FAIL: cluster_inject $m"; fail=1; }
        done
        sleep 0.6
        if kill -0 "$live" 2>/dev/null; then
            net=$(tail -n 1 "$dir/live" | sed -n 's/.* stale, \([0-9]*\) net, .*/\1/p')
            [ "${net:-0}" -ge 30 ] ||
                { echo "FAIL: fragment attacks: ${net:-no} net drops, expected >= 30"; tail -n 1 "$dir/live"; fail=1; }
            echo "    simcluster-top: fragment attacks: ${net:-?} net drops, alive"
            stop_live TERM
        else
            wait "$live"
            echo "FAIL: simcluster-top died of the fragment attacks (status $?)"; fail=1
        fi
    else
        echo "FAIL: no cluster_inject"; fail=1
    fi
    "$top" --url "$url" --key "$dir/k" --interval 3600 >"$dir/live" 2>"$dir/err" &
    live=$!
    sleep 0.5
    stop_live INT
    [ -s "$dir/err" ] && { echo "FAIL: live mode: output on stderr"; cat "$dir/err"; fail=1; }
fi
# stop the daemon as its service manager would
if [ -n "$pid" ]; then
    kill -TERM "$pid" 2>/dev/null
    i=0
    while kill -0 "$pid" 2>/dev/null && [ "$i" -lt 50 ]; do i=$((i + 1)); sleep 0.1; done
    kill -9 "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
    pid=""
fi
[ "$fail" -eq 0 ] && echo "top: all checks passed"
exit "$fail"
