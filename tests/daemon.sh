#!/bin/sh
# tests/daemon.sh BUILD - simclusterd as an operator meets it: exit statuses
# and one-line errors at start-up, then a real daemon on a private multicast
# port: it serves, logs its counters on SIGUSR1, re-reads its configuration
# on SIGHUP (keeping the old one when the new one is bad), is not root when
# started as root, and stops with status 0 on SIGTERM and SIGINT.
bin="$1/daemon/simclusterd"
tool="$1/tools/simcluster"
dir=$(mktemp -d) || exit 1
pid=""
trap '[ -n "$pid" ] && kill -9 "$pid" 2>/dev/null; rm -rf "$dir"' EXIT
trap 'exit 1' INT TERM HUP
fail=0
. "$(dirname "$0")/cli_lib.sh"
# Wait up to 5 s for the daemon to exit; its status in $rc (255: still running).
wait_exit() {
    i=0
    while kill -0 "$pid" 2>/dev/null && [ "$i" -lt 50 ]; do i=$((i + 1)); sleep 0.1; done
    if kill -0 "$pid" 2>/dev/null; then
        rc=255; kill -9 "$pid"; wait "$pid"
    else
        wait "$pid"; rc=$?
    fi
    pid=""
}

: >"$dir/empty.conf"
check "--version" 0 "$bin" --version
grep -qx "simclusterd 0.1.0" "$dir/out" || { echo "FAIL: --version says $(cat "$dir/out")"; fail=1; }
check "--help" 0 "$bin" --help
grep -q -- "--busy-threshold" "$dir/out" || { echo "FAIL: --help does not list the options"; fail=1; }
check "unknown option" 2 "$bin" --frobnicate
one_line "unknown option" "try --help"
check "--threads 0" 2 "$bin" -c "$dir/empty.conf" --insecure --threads 0
one_line "--threads 0" "threads"
check "--heartbeat out of range" 2 "$bin" -c "$dir/empty.conf" --insecure --heartbeat 11
check "--spin out of range" 2 "$bin" -c "$dir/empty.conf" --insecure --spin 0.2
one_line "--spin out of range" "spin"
check "--spin not a number" 2 "$bin" -c "$dir/empty.conf" --insecure --spin nan
check "no key, no --insecure" 1 "$bin" -c "$dir/empty.conf"
one_line "no key" "simcluster keygen"
check "keygen" 0 "$tool" keygen "$dir/k"
cp "$dir/k" "$dir/k644" && chmod 644 "$dir/k644"
check "key file mode 0644" 1 "$bin" -c "$dir/empty.conf" --key "$dir/k644"
one_line "key file mode 0644" "k644.*0600"
check "missing key file" 1 "$bin" -c "$dir/empty.conf" --key "$dir/nokey"
one_line "missing key file" "nokey"
check "missing explicit config" 1 "$bin" -c "$dir/no.conf" --insecure
one_line "missing explicit config" "no.conf"
printf '# a daemon\n\nthreads = 2\nbusy_treshold = 0.7\n' >"$dir/bad.conf"
check "unknown key" 1 "$bin" -c "$dir/bad.conf" --insecure
one_line "unknown key" "^simclusterd: $dir/bad.conf:4: "
printf 'threads = 2\nheartbeat 0.1\n' >"$dir/bad.conf"
check "missing =" 1 "$bin" -c "$dir/bad.conf" --insecure
one_line "missing =" "^simclusterd: $dir/bad.conf:2: "
printf 'heartbeat = 0.1\n\n\nbusy_threshold = 0\n' >"$dir/bad.conf"
check "bad value" 1 "$bin" -c "$dir/bad.conf" --insecure
one_line "bad value" "^simclusterd: $dir/bad.conf:4: busy_threshold"
{ printf 'url = '; i=0; while [ $i -lt 110 ]; do printf 'aaaaaaaaaa'; i=$((i + 1)); done; echo; } >"$dir/bad.conf"
check "long line" 1 "$bin" -c "$dir/bad.conf" --insecure
one_line "long line" "^simclusterd: $dir/bad.conf:1: "

# A real daemon on a port of its own (ttl=0: this host only). When we are
# root it switches to nobody, who must still read its config on SIGHUP.
port=$((20000 + $(od -An -N2 -tu2 /dev/urandom | tr -d ' ') % 10000))
url="udpm://239.255.76.67:$port?ttl=0"
chmod 755 "$dir"
# dedicated: these checks are about keys, counters and reloads, and other
# jobs loading the host must not make its owner look busy (a busy daemon is
# not counted by --wait-daemons; the owner-busy checks are cluster.sh's)
printf '# test daemon\nbusy_threshold = 0.5\nheartbeat = 0.05\nnode_id = 4660\ndedicated = yes\nspin = 0.001\n' >"$dir/d.conf"
chmod 644 "$dir/d.conf"
: >"$dir/log"
"$bin" -c "$dir/d.conf" --key "$dir/k" --url "$url" --threads 1 2>"$dir/log" &
pid=$!
if wait_log "serving"; then
    grep -q "serving on $url as node 0000000000001234 (epoch [0-9a-f]\{16\}) with 1 threads" "$dir/log" ||
        { echo "FAIL: the serving line"; cat "$dir/log"; fail=1; }
    if [ "$(id -u)" -eq 0 ]; then
        ids=$(awk '/^(Uid|Gid):/ { print $2, $3, $4, $5 }' "/proc/$pid/status")
        case " $(echo $ids) " in
            *" 0 "*) echo "FAIL: started as root, still has id 0: $ids"; fail=1 ;;
        esac
    fi
    kill -USR1 "$pid"
    if wait_log "counters:"; then
        for n in node epoch units results unit_errors shapes shape_requests dropped_format \
                 dropped_auth dropped_replay dropped_stale dropped_misaddressed dropped_net \
                 dropped_kernel challenges duplicates heartbeats spin_hits idle owner_busy; do
            grep "counters:" "$dir/log" | grep -q " $n=" || { echo "FAIL: counters lack $n"; fail=1; }
        done
    fi
    # a master with another key hears the daemon's heartbeats fail the MAC:
    # --wait-daemons says so, and a run without it warns once and counts
    "$tool" keygen "$dir/other.key" >/dev/null
    check "run --wait-daemons, another key" 1 "$tool" run bolts --bodies 5 --frames 5 \
        --cluster "$url" --key "$dir/other.key" --wait-daemons 1
    one_line "run --wait-daemons, another key" "0 daemons after 10 s, 1 wanted; [0-9]* messages failed authentication: do the daemons use this key (--key)?"
    check "run, another key" 0 "$tool" run bolts --bodies 5 --frames 100 --realtime \
        --cluster "$url" --key "$dir/other.key" --json
    one_line "run, another key" "warning: cluster messages fail authentication"
    grep -q '"dropped_auth": [1-9]' "$dir/out" ||
        { echo "FAIL: run, another key: no dropped_auth in the JSON"; cat "$dir/out"; fail=1; }
    check "run --wait-daemons, this key" 0 "$tool" run bolts --bodies 5 --frames 5 \
        --cluster "$url" --key "$dir/k" --wait-daemons 1
    # without --key the master seals with the all-zero key, and says so
    check "run without --key" 0 "$tool" run bolts --bodies 5 --frames 5 --cluster "$url"
    grep -q "^simcluster: run: no --key: .*all-zero key" "$dir/err" ||
        { echo "FAIL: run without --key: the all-zero key is not named"; cat "$dir/err"; fail=1; }
    # idle again, it sleeps: at most 10 % of a CPU over a second (its
    # compute thread polls for units only for --spin after one ran)
    cpu_ticks() { awk '{ print $14 + $15 }' "/proc/$pid/stat"; }
    t0=$(cpu_ticks); sleep 1; t1=$(cpu_ticks)
    hz=$(getconf CLK_TCK)
    [ $((t1 - t0)) -le $((hz / 10)) ] ||
        { echo "FAIL: an idle daemon used $((t1 - t0)) of $hz ticks in a second"; fail=1; }
    sed -e 's/^busy_threshold = 0.5/busy_threshold = 0.75/' -e 's/^node_id = 4660/node_id = 4661/' \
        -e 's/^spin = 0.001/spin = 0.003/' "$dir/d.conf" >"$dir/d2.conf" && cat "$dir/d2.conf" >"$dir/d.conf"
    kill -HUP "$pid"
    wait_log "busy_threshold 0.5 -> 0.75"
    wait_log "node_id 4660 -> 4661 needs a restart"
    wait_log "spin 0.001 -> 0.003 needs a restart"
    printf 'busy_threshold = 2\n' >>"$dir/d.conf"
    kill -HUP "$pid"
    wait_log "d.conf:7: .*keeping the old configuration"
    kill -TERM "$pid"
    wait_exit
    [ "$rc" -eq 0 ] || { echo "FAIL: SIGTERM: exit $rc, expected 0 within 5 s"; cat "$dir/log"; fail=1; }
    [ "$(grep -c "counters:" "$dir/log")" -eq 2 ] ||
        { echo "FAIL: no counters line at exit"; cat "$dir/log"; fail=1; }
    grep -v "^simclusterd\[[0-9]*\]: " "$dir/log" >"$dir/other"
    [ -s "$dir/other" ] && { echo "FAIL: log lines not from simclusterd:"; cat "$dir/other"; fail=1; }
fi
[ -n "$pid" ] && { kill -9 "$pid" 2>/dev/null; wait "$pid"; pid=""; }

# --dedicated (here from the config file): two CPU hogs on a 2-core host
# and still all idle, never owner-busy
printf 'dedicated = yes\nbusy_threshold = 0.5\nheartbeat = 0.05\n' >"$dir/ded.conf"
chmod 644 "$dir/ded.conf"
: >"$dir/log"
"$bin" -c "$dir/ded.conf" --insecure --url "$url" --threads 1 2>"$dir/log" &
pid=$!
if wait_log "serving"; then
    # (started from a subshell: not our jobs, so no "Killed" when they go)
    hogs=$( (sh -c 'while :; do :; done' >/dev/null 2>&1 & echo $!
             sh -c 'while :; do :; done' >/dev/null 2>&1 & echo $!) )
    sleep 0.6
    kill -USR1 "$pid"
    wait_log "counters:" && { grep "counters:" "$dir/log" | grep -q "idle=1.000 owner_busy=0" ||
        { echo "FAIL: --dedicated: $(grep counters: "$dir/log")"; fail=1; }; }
    kill -9 $hogs
    kill -TERM "$pid"
    wait_exit
fi
[ -n "$pid" ] && { kill -9 "$pid" 2>/dev/null; wait "$pid"; pid=""; }

# Hostile LCM fragments against a daemon held to 320 MB of address space
# (it uses about 100): LCM 1.3.1 died of each of these (a second fragment
# at offset 0xFFFFFFF0 wraps its 32-bit bounds check; a 256 MB claim is
# malloc'd as told). Each is refused and counted (dropped_net), and a burst
# of 1000 forged envelopes, sent at once, is counted whole (dropped_auth).
# Under ASan (which reserves terabytes) without the limit.
inject="$1/tests/cluster_inject"
[ -x "$inject" ] || inject="build/tests/cluster_inject"
vlimit=320000
grep -q __asan_init "$bin" && vlimit=unlimited
if [ -x "$inject" ]; then
    : >"$dir/log"
    (ulimit -v "$vlimit" && exec "$bin" -c "$dir/empty.conf" --key "$dir/k" --url "$url" \
        --threads 1 --node-id 4662 2>"$dir/log") &
    pid=$!
    if wait_log "serving"; then
        for m in frag-wrap frag-huge frag-4g; do
            "$inject" --url "$url" --key "$dir/k" --channel SC_UNIT_0000000000001236 \
                --mode "$m" --count 20 --pace-us 0 >/dev/null ||
                { echo "FAIL: cluster_inject --mode $m"; fail=1; }
        done
        "$inject" --url "$url" --key "$dir/k" --channel SC_UNIT_0000000000001236 \
            --mode wrongkey --count 1000 --pace-us 0 >/dev/null ||
            { echo "FAIL: cluster_inject burst"; fail=1; }
        sleep 0.5
        if kill -0 "$pid" 2>/dev/null; then
            kill -USR1 "$pid"
            if wait_log "counters:"; then
                line=$(grep "counters:" "$dir/log" | tail -n 1)
                net=$(echo "$line" | sed -n 's/.* dropped_net=\([0-9]*\) .*/\1/p')
                auth=$(echo "$line" | sed -n 's/.* dropped_auth=\([0-9]*\) .*/\1/p')
                kern=$(echo "$line" | sed -n 's/.* dropped_kernel=\([0-9]*\) .*/\1/p')
                # 20 wrapping second fragments, 20 + 20 huge claims; the 20
                # half messages are evicted later (or already)
                [ "${net:-0}" -ge 60 ] ||
                    { echo "FAIL: fragment attacks: dropped_net=${net:-?}, expected >= 60"; fail=1; }
                # every packet counted; as root (a receive buffer of 8 MiB
                # whatever net.core.rmem_max says) none lost in the kernel
                kmax=1000
                [ "$(id -u)" -eq 0 ] && kmax=0
                [ $((${auth:-0} + ${kern:-0})) -eq 1000 ] && [ "${kern:-0}" -le $kmax ] ||
                    { echo "FAIL: burst of 1000: dropped_auth=${auth:-?} dropped_kernel=${kern:-?}"; fail=1; }
                echo "    daemon (ulimit -v $vlimit): fragment attacks dropped_net=$net, burst of 1000: dropped_auth=$auth dropped_kernel=$kern"
            fi
            kill -TERM "$pid"
            wait_exit
            [ "$rc" -eq 0 ] || { echo "FAIL: after the attacks: exit $rc"; fail=1; }
        else
            wait "$pid"
            echo "FAIL: the daemon died of the fragment attacks (status $?)"; cat "$dir/log"
            pid=""
            fail=1
        fi
    fi
    [ -n "$pid" ] && { kill -9 "$pid" 2>/dev/null; wait "$pid"; pid=""; }
else
    echo "FAIL: no cluster_inject (make $1/tests/cluster_inject)"; fail=1
fi

# --insecure starts without a key, says so, and SIGINT stops it too.
: >"$dir/log"
"$bin" -c "$dir/empty.conf" --insecure --url "$url" --threads 1 --heartbeat 0.05 2>"$dir/log" &
pid=$!
if wait_log "serving"; then
    grep -q "insecure" "$dir/log" || { echo "FAIL: --insecure is not logged"; fail=1; }
    kill -INT "$pid"
    wait_exit
    [ "$rc" -eq 0 ] || { echo "FAIL: SIGINT: exit $rc, expected 0 within 5 s"; cat "$dir/log"; fail=1; }
fi
[ -n "$pid" ] && { kill -9 "$pid" 2>/dev/null; wait "$pid"; pid=""; }
[ "$fail" -eq 0 ] && echo "daemon: all checks passed"
exit "$fail"
