#!/bin/sh
# bench/figs34.sh [-q] [-o OUTDIR] [-n LIST] [-s SEED] [-r RUNS] [-b BUILD] - the
# paper's Figs 3 and 4 on one machine (POSIX sh; needs root).
#
# The paper drops N = 1..50 bolts and nuts onto a floor and measures the
# wall time until all are at rest on (1) 4 PCs (1.26, 1.0, 1.0 and 0.7 GHz,
# dual CPU) on 100BASE-T, (2) the same on 10BASE-T, (3) 2 PCs (1.26, 1.0)
# on 10BASE-T, (4) 1 PC (1.26). Fig 3 = conditions 1 and 2, Fig 4 = 2, 3, 4.
# Here each PC is emulated:
#   - its CPU: a cgroup with a CPU quota (cgroup v1 cpu.cfs_quota_us or v2
#     cpu.max, whichever this kernel has), the quotas in the paper's speed
#     ratios scaled to sum to at most 95 % of the CPUs this script may use;
#     the master (the 1.26 node) runs `simcluster run --workers 2` and each
#     daemon simclusterd --threads 2 (dual CPU) inside its node's quota;
#   - its network: a namespace of its own and a veth to a bridge in yet
#     another namespace (as tests/cluster.sh), both ends of each veth shaped
#     with tc: an htb class at the link rate (100 or 10 Mbit/s) and a netem
#     delay under it (LINK_DELAY_US each way per veth end, ~ switch and NIC
#     latency of switched Ethernet around 2000). Nothing leaves those
#     namespaces: the bridge has no uplink and the URL has ttl=1.
#     Programs enter a namespace with nsenter --net (not ip netns exec,
#     which mounts a sysfs of its own over /sys and so hides the cgroup
#     files): each sees its quota (sc_cpu_budget()) and its idle threads
#     sleep rather than poll away a quota smaller than its threads.
# For each condition and N it runs
#   simcluster run bolts --bodies N --seed S --until-rest --json
#     [--cluster URL --key KEY --wait-daemons K]
# and writes OUTDIR/figs34.csv, OUTDIR/fig3.png, OUTDIR/fig4.png (gnuplot)
# and OUTDIR/figs34.md (a README section: setup, table, derived figures
# next to the paper's). Each point is the median of RUNS runs (default 3);
# -q: N = 1 5 20, one run each, for a smoke test. FIGS34_ARGS (environment):
# more options for every run, e.g. FIGS34_ARGS="--min-gain -1".
# Not root, or no netns, tc or cgroup cpu controller: prints SKIPPED and
# exits 0. Everything it makes (namespaces, veths, bridge, cgroups,
# daemons, the key) is removed on exit, error or Ctrl-C.
cd "$(dirname "$0")/.." || exit 1
ROOT=$PWD

usage() {
    echo "usage: bench/figs34.sh [-q] [-o OUTDIR] [-n 'N1 N2 ...'] [-s SEED] [-r RUNS] [-b BUILD]" >&2
    exit 2
}
OUT=$ROOT/build/figs34
LIST="1 2 3 5 7 9 12 15 18 21 25 30 35 40 45 50"
SEED=1
RUNS=3
BUILD=$ROOT/build
while getopts qo:n:s:r:b: opt; do
    case $opt in
    q) LIST="1 5 20"; RUNS=1 ;;
    o) OUT=$OPTARG ;;
    n) LIST=$(echo "$OPTARG" | tr ',' ' ') ;;
    s) SEED=$OPTARG ;;
    r) RUNS=$OPTARG ;;
    b) BUILD=$OPTARG ;;
    *) usage ;;
    esac
done
shift $((OPTIND - 1))
[ $# -eq 0 ] || usage
for n in $LIST; do
    case $n in '' | *[!0-9]*) usage ;; esac
    [ "$n" -ge 1 ] || usage
done
case $SEED in '' | *[!0-9]*) usage ;; esac
case $RUNS in '' | *[!0-9]* | 0) usage ;; esac
case $OUT in /*) ;; *) OUT=$ROOT/$OUT ;; esac
case $BUILD in /*) ;; *) BUILD=$ROOT/$BUILD ;; esac
LIST=$(for n in $LIST; do echo "$n"; done | sort -n | uniq | tr '\n' ' ' | sed 's/ $//')
SIM=$BUILD/tools/simcluster
DAEMON=$BUILD/daemon/simclusterd

SPEEDS="1.26 1.0 1.0 0.7"       # the paper's PCs, GHz: master, d1, d2, d3
PERIOD_US=10000                 # CFS period: one frame, so throttling stalls stay short
LINK_DELAY_US=50                # netem delay on each veth end (one way: 2 x this)
RUN_LIMIT=600                   # s, one simcluster run at most

# shellcheck disable=SC2034 # read by bench/emulate.sh
NAME=figs34
# shellcheck source=bench/emulate.sh
. "$ROOT/bench/emulate.sh"
emu_require
tag=$$
"$SIM" --help | grep -q wait-daemons ||
    { echo "figs34: $SIM has no --wait-daemons (rebuild)" >&2; exit 1; }
PLOT=1
if ! command -v gnuplot >/dev/null 2>&1; then
    # as root scripts/deps.sh installs it; it prints the apt-get line otherwise
    sh scripts/deps.sh bench || PLOT=0
    command -v gnuplot >/dev/null 2>&1 || PLOT=0
fi

br=scfbr$tag; nsm=scf${tag}m; ns1=scf${tag}d1; ns2=scf${tag}d2; ns3=scf${tag}d3
CG=$CGROOT/simfigs$tag
dir=$(mktemp -d /tmp/scfigs.XXXXXX) || exit 1
pids=""

cleanup() {
    trap - EXIT INT TERM
    # shellcheck disable=SC2086 # pids: words
    emu_stop $pids
    for ns in "$nsm" "$ns1" "$ns2" "$ns3" "$br"; do ip netns del "$ns" 2>/dev/null; done
    # anything still in our cgroups was started by this script
    for g in m d1 d2 d3; do emu_cg_remove "$CG/$g"; done
    [ -d "$CG" ] && rmdir "$CG"
    emu_restore
    rm -rf "$dir"
}
# fd 3: our stderr; dash may run a trap with a command's redirections in force
exec 3>&2
trap cleanup EXIT
trap 'echo "figs34: interrupted" >&3; exit 130' INT TERM
die() { echo "figs34: $*" >&2; exit 1; }

# ---- CPU quotas: the speed ratios, summing to <= 95 % of our CPUs ----
ncpu=$(nproc)
total=$(echo "$SPEEDS" | awk '{ for (i = 1; i <= NF; i++) s += $i; print s }')
# the quota of a node is at most its 2 threads; scale <= 1 keeps 1.26 -> 1.26 CPUs
scale=$(awk -v n="$ncpu" -v t="$total" 'BEGIN { s = 0.95 * n / t; if (s > 1) s = 1; print s }')
set -- $SPEEDS
q_m=$(awk -v g="$1" -v s="$scale" -v p=$PERIOD_US 'BEGIN { printf "%d", g * s * p + 0.5 }')
q_d1=$(awk -v g="$2" -v s="$scale" -v p=$PERIOD_US 'BEGIN { printf "%d", g * s * p + 0.5 }')
q_d2=$(awk -v g="$3" -v s="$scale" -v p=$PERIOD_US 'BEGIN { printf "%d", g * s * p + 0.5 }')
q_d3=$(awk -v g="$4" -v s="$scale" -v p=$PERIOD_US 'BEGIN { printf "%d", g * s * p + 0.5 }')
cpus() { awk -v q="$1" -v p=$PERIOD_US 'BEGIN { printf "%.3f", q / p }'; }
qsum=$(cpus $((q_m + q_d1 + q_d2 + q_d3)))

mkcg() {
    emu_cg_parent "$CG" || return 1
    for g in m d1 d2 d3; do
        eval "q=\$q_$g"
        emu_cg_child "$CG/$g" "$q" "$PERIOD_US" || return 1
    done
}
mkcg || emu_skip "cannot make cgroups with CPU quotas under $CGROOT"
procs_file() { if [ "$CGV" = 1 ]; then echo tasks; else echo cgroup.procs; fi; }
PROCS=$(procs_file)
# in_cg GROUP CMD...: CMD in that cgroup (the shell joins it, then execs);
# for a background CMD whose pid counts, write the sh -c line out instead
# (a function run with & is a subshell that a kill leaves CMD to)
JOIN='echo $$ >"$0" && exec "$@"'
in_cg() {
    g=$1
    shift
    sh -c "$JOIN" "$CG/$g/$PROCS" "$@"
}
throttled() { emu_throttled "$CG/$1"; }   # the cgroup of node $1

# ---- network: a bridge in its own namespace, a shaped veth to each node ----
plumb() {
    emu_bridge "$br" || return 1
    i=1
    for ns in "$nsm" "$ns1" "$ns2" "$ns3"; do
        emu_node "$ns" "$br" "p$i" "10.214.34.$i" || return 1
        # both directions of the node's link: htb at the rate, netem delay
        # under it (here the kernel has none: CONFIG_NET_SCH_NETEM unset)
        emu_shape "$ns" eth0 100mbit "$LINK_DELAY_US" &&
            emu_shape "$br" "p$i" 100mbit "$LINK_DELAY_US" || return 1
        i=$((i + 1))
    done
}
set_rate() { # $1: 100mbit or 10mbit, on every shaped veth end
    i=1
    for ns in "$nsm" "$ns1" "$ns2" "$ns3"; do
        for end in "$ns eth0" "$br p$i"; do
            set -- $end
            tc -n "$1" class change dev "$2" parent 1: classid 1:1 htb rate "$RATE" \
                ceil "$RATE" quantum 1514 || return 1
        done
        i=$((i + 1))
    done
}
plumb || die "network namespaces, bridge, veths or tc qdiscs could not be made"
emu_rmem
port=$((20000 + $(od -An -N2 -tu2 /dev/urandom) % 40000))
URL="udpm://239.255.76.67:$port?ttl=1&recv_buf_size=4194304"
KEY=$dir/key
"$SIM" keygen "$KEY" >/dev/null || die "simcluster keygen failed"
mkdir -p "$OUT/raw" || die "cannot make $OUT/raw"

# ---- daemons ----
start_daemon() { # $1 = 1..3; waits for its "serving" line
    eval "ns=\$ns$1"
    log=$dir/d$1.log
    : >"$log"
    sh -c "$JOIN" "$CG/d$1/$PROCS" nsenter --net="/run/netns/$ns" "$DAEMON" --url "$URL" --key "$KEY" \
        --threads 2 --dedicated --heartbeat 0.1 --node-id $((3400 + $1)) >>"$log" 2>&1 &
    eval "dpid$1=$!"
    pids="$pids $!"
    tries=0
    while ! grep -q serving "$log"; do
        tries=$((tries + 1))
        if [ $tries -gt 200 ] || ! kill -0 "$(eval "echo \$dpid$1")" 2>/dev/null; then
            echo "figs34: daemon $1 did not start:" >&2
            tail -n 20 "$log" >&2
            return 1
        fi
        sleep 0.05
    done
}
stop_daemon() { # $1 = 1..3: the units it computed in $units_seen
    p=$(eval "echo \$dpid$1")
    kill -USR1 "$p" 2>/dev/null
    sleep 0.2
    cline=$(grep 'counters:' "$dir/d$1.log" | tail -n 1)
    units_seen=$(echo "$cline" | grep -o ' units=[0-9]*' | cut -d= -f2)
    kill -TERM "$p" 2>/dev/null
    tries=0
    while kill -0 "$p" 2>/dev/null && [ $tries -lt 100 ]; do sleep 0.05; tries=$((tries + 1)); done
    kill -9 "$p" 2>/dev/null
    wait "$p" 2>/dev/null
}

# ---- one run: simcluster's JSON into raw/, a CSV row ----
jnum() { sed -n "s/.*\"$2\": \([-0-9.e]*\).*/\1/p" "$1"; }
jstr() { sed -n "s/.*\"$2\": \"\([^\"]*\)\".*/\1/p" "$1"; }
jbool() { sed -n -e "s/.*\"$2\": true.*/true/p" -e "s/.*\"$2\": false.*/false/p" "$1"; }
CSV=$OUT/figs34.csv
echo "condition,nodes,link,bodies,seed,wall_s,simulated_s,at_rest,realtime,frames,frames_over_budget,over_share,max_frame_s,units,remote_units,remote_share,recomputed_units,late_results,daemons,hash,same_hash" >"$CSV"
run_one() { # $1 = condition, $2 = nodes, $3 = link label, $4 = N, $5 = daemons to wait for
    c=$1 nodes=$2 link=$3 n=$4 wait=$5
    j=$OUT/raw/c${c}_n$n.json
    set -- "$SIM" run bolts --bodies "$n" --seed "$SEED" --until-rest --workers 2 --json
    [ "$wait" -gt 0 ] && set -- "$@" --cluster "$URL" --key "$KEY" --wait-daemons "$wait"
    # shellcheck disable=SC2086 # FIGS34_ARGS: words
    [ -n "${FIGS34_ARGS:-}" ] && set -- "$@" $FIGS34_ARGS
    # RUNS runs; the one with the median wall time stands for them (its
    # JSON is $j, the others $j.rR); every run's hash must be the same
    r=1
    hashes=""
    while [ $r -le "$RUNS" ]; do
        if ! in_cg m timeout --foreground -k 2 $RUN_LIMIT nsenter --net="/run/netns/$nsm" "$@" >"$j.r$r" \
            2>"$j.err" || [ -z "$(jnum "$j.r$r" wall_s)" ]; then
            echo "figs34: condition $c, N=$n failed:" >&2
            cat "$j.err" "$j.r$r" >&2
            return 1
        fi
        hashes="$hashes $(jstr "$j.r$r" hash)"
        r=$((r + 1))
    done
    med=$(for r in $(seq 1 "$RUNS"); do echo "$(jnum "$j.r$r" wall_s) $r"; done | sort -n |
        awk -v k="$RUNS" 'NR == int((k + 1) / 2) { print $2 }')
    mv "$j.r$med" "$j"
    [ -s "$j.err" ] || rm -f "$j.err"
    nh=$(echo "$hashes" | tr ' ' '\n' | sed '/^$/d' | sort -u | wc -l)
    wall=$(jnum "$j" wall_s); sim=$(jnum "$j" simulated_s); rest=$(jbool "$j" at_rest)
    fr=$(jnum "$j" frames); over=$(jnum "$j" frames_over_budget)
    maxf=$(jnum "$j" max_frame_s); units=$(jnum "$j" units); remote=$(jnum "$j" remote_units)
    recomp=$(jnum "$j" recomputed_units); late=$(jnum "$j" late_results)
    nd=$(jnum "$j" daemons); h=$(jstr "$j" hash)
    rt=$(awk -v w="$wall" -v s="$sim" 'BEGIN { print (w <= s) ? "yes" : "no" }')
    share=$(awk -v o="$over" -v f="$fr" 'BEGIN { printf "%.3f", (f > 0 ? o / f : 0) }')
    rshare=$(awk -v r="$remote" -v u="$units" 'BEGIN { printf "%.3f", (u > 0 ? r / u : 0) }')
    if [ "$c" = 4 ]; then
        eval "H$n=$h"
        same=ref
    else
        same=$(eval "[ \"\$H$n\" = $h ] && echo yes || echo NO")
    fi
    [ "$nh" -eq 1 ] || same=NO
    echo "$c,$nodes,$link,$n,$SEED,$wall,$sim,$rest,$rt,$fr,$over,$share,$maxf,$units,$remote,$rshare,$recomp,$late,$nd,$h,$same" >>"$CSV"
    printf '  %-2s %-5s %5s %8.3f %8.2f %5s %4s/%-5s %7.1f %7.1f%% %6s %s\n' "$n" "$nodes" \
        "$link" "$wall" "$sim" "$rt" "$over" "$fr" "$(awk -v m="$maxf" 'BEGIN { print 1e3 * m }')" \
        "$(awk -v r="$rshare" 'BEGIN { print 100 * r }')" "$recomp" "$same"
}
header() {
    printf '  %-2s %-5s %5s %8s %8s %5s %10s %7s %8s %6s %s\n' N nodes link "wall s" "sim s" \
        "RT" "over/fr" "max ms" "remote" recomp "same hash"
}

# ---- the four conditions (4 first: the reference hashes) ----
echo "figs34: cgroup v$CGV at $CGROOT, CPU quotas per period of $PERIOD_US us (scale $scale of"
echo "  the paper's GHz; $ncpu CPUs): master (1.26) $q_m us = $(cpus "$q_m") CPU," \
    "d1 (1.0) $q_d1 = $(cpus "$q_d1"), d2 (1.0) $q_d2 = $(cpus "$q_d2")," \
    "d3 (0.7) $q_d3 = $(cpus "$q_d3"); sum $qsum CPU"
if [ "$EMU_NETEM" = 1 ]; then
    LAT="htb at 100 or 10 Mbit/s on both ends of each node's veth, netem delay $LINK_DELAY_US µs under it: node to node $((2 * LINK_DELAY_US)) µs one way ($((4 * LINK_DELAY_US)) µs round trip) plus the serialisation of each of the 2 shaped hops (a store-and-forward switch: 120 µs a 1500-byte frame at 100 Mbit/s, 1.2 ms at 10 Mbit/s)"
else
    LAT="htb at 100 or 10 Mbit/s on both ends of each node's veth; this kernel has no netem (CONFIG_NET_SCH_NETEM unset), so no added delay: the latency is the serialisation of each of the 2 shaped hops (a store-and-forward switch: 120 µs a 1500-byte frame at 100 Mbit/s, 1.2 ms at 10 Mbit/s) and the kernel's own few µs"
fi
echo "figs34: links: $LAT"
echo "figs34: N = $LIST, seed $SEED, median of $RUNS run(s); $URL (ttl=1, inside the namespaces only)"
t_start=$(date +%s)
fail=0
IDLE=""
for c in 4 1 2 3; do
    case $c in
    1) nodes=4; RATE=100mbit; K=3 ;;
    2) nodes=4; RATE=10mbit; K=3 ;;
    3) nodes=2; RATE=10mbit; K=1 ;;
    4) nodes=1; RATE=-; K=0 ;;
    esac
    link=$(echo "$RATE" | sed 's/mbit/M/')
    echo "figs34: condition $c: $nodes node(s), link $RATE"
    if [ $K -gt 0 ]; then
        set_rate "$RATE" || die "tc class change failed"
        for d in $(seq 1 $K); do start_daemon "$d" || die "daemon $d did not start"; done
    fi
    thr0=$(throttled m)
    header
    for n in $LIST; do
        run_one $c $nodes "$link" "$n" $K || fail=$((fail + 1))
    done
    thr1=$(throttled m)
    echo "  (master cgroup throttled $(awk -v a="$thr0" -v b="$thr1" 'BEGIN { printf "%.1f", b - a }') s in this condition)"
    if [ $K -gt 0 ]; then
        line=""
        for d in $(seq 1 $K); do
            stop_daemon "$d"
            line="$line d$d ${units_seen:-?}"
        done
        echo "  units the daemons computed in this condition:$line"
        IDLE="$IDLE
- condition $c:$line"
    fi
done
elapsed=$(($(date +%s) - t_start))

# ---- derived figures ----
# wall time of condition $1 at N $2
wall_of() { awk -F, -v c="$1" -v n="$2" '$1 == c && $4 == n { print $6 }' "$CSV"; }
# largest N of the list up to which every run (criterion column $2: 9 =
# wall <= simulated, 11 = no frame over budget) held real time
rt_max() {
    awk -F, -v c="$1" -v col="$2" 'NR > 1 && $1 == c {
        ok = col == 9 ? $9 == "yes" : $11 == 0
        if (ok && !broken) best = $4; else broken = 1 }
        END { print best == "" ? "none" : best }' "$CSV"
}
NMAX=$(echo "$LIST" | awk '{ print $NF }')
w1=$(wall_of 1 "$NMAX")
w4=$(wall_of 4 "$NMAX")
speedup=$(awk -v a="$w4" -v b="$w1" 'BEGIN { if (a > 0 && b > 0) printf "%.2f", a / b; else print "-" }')
# the smallest N from which condition 1 beats condition 4 at every larger N of the list
cross=$(awk -F, 'NR > 1 && $1 == 1 { w1[$4] = $6 } NR > 1 && $1 == 4 { w4[$4] = $6 }
    END { for (n in w1) ns[++k] = n + 0
        for (i = 1; i <= k; i++) for (j = i + 1; j <= k; j++) if (ns[j] < ns[i]) { t = ns[i]; ns[i] = ns[j]; ns[j] = t }
        c = "none"
        for (i = k; i >= 1; i--) { n = ns[i]; if ((n in w4) && w1[n] < w4[n]) c = n; else break }
        print c }' "$CSV")
diffs=$(awk -F, 'NR > 1 && $21 == "NO"' "$CSV" | wc -l)
echo "figs34: largest N in real time (wall <= simulated, every N up to it):" \
    "cond1 $(rt_max 1 9), cond2 $(rt_max 2 9), cond3 $(rt_max 3 9), cond4 $(rt_max 4 9)" \
    "(paper: 21 with 4 PCs, 9 with 1)"
echo "figs34: largest N with no frame over 10 ms: cond1 $(rt_max 1 11), cond2 $(rt_max 2 11)," \
    "cond3 $(rt_max 3 11), cond4 $(rt_max 4 11)"
echo "figs34: speedup of 4 nodes (100M) over 1 at N=$NMAX: $speedup (paper at 50: ~2.3)"
echo "figs34: cluster (cond1) faster than one node from N=$cross on (paper: from 15)"
echo "figs34: runs with a hash different from condition 4's: $diffs; failed runs: $fail"

# ---- plots ----
if [ $PLOT = 1 ]; then
    for f in 3 4; do
        if [ $f = 3 ]; then conds="1 2"; else conds="2 3 4"; fi
        cmd="set terminal pngcairo size 800,560 font ',11'; set output '$OUT/fig$f.png';"
        cmd="$cmd set datafile separator ','; set key top left; set grid;"
        cmd="$cmd set xlabel 'bolts and nuts N'; set ylabel 'time until all at rest (s)';"
        cmd="$cmd set title 'Fig $f (emulated): wall time until rest; seed $SEED';"
        cmd="$cmd plot '$CSV' using (\$1 == ${conds%% *} ? \$4 : 1/0):7 with lines dt 2 lc 'black' title 'simulated time (real time)'"
        for c in $conds; do
            case $c in
            1) t="4 nodes, 100 Mbit/s" ;;
            2) t="4 nodes, 10 Mbit/s" ;;
            3) t="2 nodes, 10 Mbit/s" ;;
            4) t="1 node" ;;
            esac
            cmd="$cmd, '$CSV' using (\$1 == $c ? \$4 : 1/0):6 with linespoints lw 2 title '$t'"
        done
        gnuplot -e "$cmd" || echo "figs34: gnuplot failed for fig$f" >&2
    done
else
    echo "figs34: no gnuplot: no fig3.png, fig4.png (install: apt-get install gnuplot-nox)"
fi

# ---- the markdown section ----
MD=$OUT/figs34.md
{
    echo "## Figs 3–4: time until rest on 4, 2 and 1 emulated PCs"
    echo
    echo "\`bench/figs34.sh -s $SEED -r $RUNS -n '$LIST'\` (as root; $(date -u +%Y-%m-%d), $elapsed s)."
    echo "Each PC of the paper is a network namespace with a CPU quota:"
    echo
    echo "- CPU: cgroup v$CGV ($CGROOT), period $PERIOD_US µs; quotas in the paper's"
    echo "  1.26 : 1.0 : 1.0 : 0.7 GHz scaled by $scale to fit this machine's $ncpu CPUs:"
    echo "  master $q_m µs ($(cpus "$q_m") CPU), d1 $q_d1 ($(cpus "$q_d1")), d2 $q_d2"
    echo "  ($(cpus "$q_d2")), d3 $q_d3 ($(cpus "$q_d3")); sum $qsum CPU. The master is the 1.26"
    echo "  node and computes too (\`--workers 2\`, dual CPU); each daemon is \`simclusterd"
    echo "  --threads 2 --dedicated\` (no owner: the other emulated PCs on the same CPUs must not count as one)."
    echo "- Network: a veth per node to a bridge (multicast floods every port, as on a"
    echo "  switch without IGMP snooping), shaped with tc: $LAT. LCM multicast with ttl=1"
    echo "  inside the namespaces."
    echo "- Runs: \`simcluster run bolts --bodies N --seed $SEED --until-rest --workers 2 --json\`"
    echo "  (+ \`--cluster URL --key KEY --wait-daemons K\` on 2 or 4 nodes); each point the"
    echo "  run with the median wall time of $RUNS."
    echo "  Our frames are 0.01 s (the paper's 0.1 s)."
    echo
    echo "Wall time until all bodies are at rest (s; simulated time in the second column;"
    echo "\\* = slower than real time; the share of frames whose step took over 10 ms and"
    echo "of units computed by daemons in brackets):"
    echo
    echo "| N | simulated s | 4 nodes 100M | 4 nodes 10M | 2 nodes 10M | 1 node |"
    echo "|---|---|---|---|---|---|"
    for n in $LIST; do
        awk -F, -v n="$n" 'NR > 1 && $4 == n { sim = $7
                cell[$1] = sprintf("%.3f%s (%.0f %% late fr, %.0f %% remote)", $6,
                                   $9 == "yes" ? "" : "\\*", 100 * $12, 100 * $16) }
            END { printf "| %s | %.2f | %s | %s | %s | %s |\n", n, sim, cell[1], cell[2],
                  cell[3], cell[4] }' "$CSV"
    done
    echo
    echo "| figure | here | paper |"
    echo "|---|---|---|"
    echo "| largest N in real time (wall ≤ simulated, every N up to it), 4 nodes 100M | $(rt_max 1 9) | 21 |"
    echo "| same, 1 node | $(rt_max 4 9) | 9 |"
    echo "| same, 4 nodes 10M / 2 nodes 10M | $(rt_max 2 9) / $(rt_max 3 9) | – |"
    echo "| largest N with no frame over 10 ms (4 nodes 100M / 1 node) | $(rt_max 1 11) / $(rt_max 4 11) | – |"
    echo "| speedup of 4 nodes (100M) over 1 node at N = $NMAX | $speedup× | ≈ 2.3× at N = 50 |"
    echo "| N from which 4 nodes beat 1 node (at every larger N measured) | $cross | 15 |"
    echo "| runs whose final state differs from the 1-node run's | $diffs | – |"
    echo
    echo "Units each daemon computed in each condition (all runs):$IDLE"
    echo
    echo "![Fig 3](fig3.png) ![Fig 4](fig4.png)"
} >"$MD"
echo "figs34: wrote $CSV, $MD$( [ $PLOT = 1 ] && echo ", $OUT/fig3.png, $OUT/fig4.png")"
[ $fail -eq 0 ]
