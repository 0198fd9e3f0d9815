#!/bin/sh
# bench/pcs.sh [-q] [-o OUTDIR] [-k 'K1 K2 ...'] [-S 'SCENE:BODIES:FRAMES ...'] [-r RUNS]
#              [-b BUILD] - 1, 2, 4 and 8 PCs emulated on this machine, at the sizes
# where sharing matters (POSIX sh; needs root).
#
# Each PC is a network namespace with a CPU quota, as in bench/figs34.sh:
#   - its CPU: a cgroup (v1 cpu.cfs_quota_us or v2 cpu.max) with the same quota
#     for every PC, 95 % of the CPUs this script may use over the most PCs of the
#     list, so that all of them together fit; the one-PC baseline runs under the
#     same quota. PC 1 runs the master (`simcluster run --workers 1`), each other
#     PC one daemon (`simclusterd --threads 1 --dedicated`);
#   - its network: a veth to a bridge in a namespace of its own, both ends
#     shaped with tc htb at an office LAN's rate (1 Gbit/s) scaled by the same
#     factor as the CPU (a PC at a quarter of a CPU gets 250 Mbit/s), so that
#     transfer time against compute time stays as on real PCs; with netem (not
#     on every kernel) also a delay of the LAN's 100 µs one way, scaled the same.
# For each scene and PC count it runs
#   simcluster run SCENE --bodies N --frames F --seed 1 --workers 1 --json
#     [--cluster URL --key KEY --wait-daemons K-1]
# and prints per frame: wall time, speedup over one PC, the share of units
# daemons computed, the master's serial part (sc_stats serial_s), its
# communication time, messages and estimated bytes per daemon, and a
# prediction. The model (below) is with inputs from the 2-PC row predicts the
# 4- and 8-PC rows before they run, and 16 PCs. Writes OUTDIR/pcs.md and the
# runs' JSON in OUTDIR/raw. -q: bin 200 for 20 frames on 1 and 2 PCs (a smoke
# test). Not root, or no netns, tc or cgroup cpu controller: prints SKIPPED
# and exits 0. Everything it makes is removed on exit, error or Ctrl-C.
#
# The model, per frame, from the 2-PC run (one master, one daemon): S the
# master's serial part, W the units' work, J the jobs, I(n) the least time of
# those jobs on n nodes of the measured speed with free messages
# (sc_stats ideal_makespan_s) and L a daemon's round trip less its work (per
# job it answered). k PCs take T(k) = S + min(W, I(k) + J L): every job that
# ships pays one round trip, and the master keeps a job whole where that is
# cheaper. It leaves out the greedy's imbalance, per-byte costs and the
# quota's stalls.
cd "$(dirname "$0")/.." || exit 1
ROOT=$PWD

usage() {
    echo "usage: bench/pcs.sh [-q] [-o OUTDIR] [-k 'K1 K2 ...'] [-S 'SCENE:BODIES:FRAMES ...'] [-r RUNS] [-b BUILD]" >&2
    exit 2
}
OUT=$ROOT/build/pcs
KLIST="1 2 4 8"
SCENES="bin:1000:60 bin:4000:20"
RUNS=1
BUILD=$ROOT/build
while getopts qo:k:S:r:b: opt; do
    case $opt in
    q) KLIST="1 2"; SCENES="bin:200:20"; RUNS=1 ;;
    o) OUT=$OPTARG ;;
    k) KLIST=$(echo "$OPTARG" | tr ',' ' ') ;;
    S) SCENES=$OPTARG ;;
    r) RUNS=$OPTARG ;;
    b) BUILD=$OPTARG ;;
    *) usage ;;
    esac
done
shift $((OPTIND - 1))
[ $# -eq 0 ] || usage
for k in $KLIST; do
    case $k in '' | *[!0-9]*) usage ;; esac
    if [ "$k" -lt 1 ] || [ "$k" -gt 16 ]; then usage; fi
done
KLIST=$(for k in $KLIST; do echo "$k"; done | sort -n | uniq | tr '\n' ' ' | sed 's/ $//')
case " $KLIST " in *" 1 "*) ;; *) echo "pcs: the list needs 1 (the baseline)" >&2; usage ;; esac
for s in $SCENES; do
    case $s in *:*[!0-9:]* | *::* | :*) usage ;; esac
    [ "$(echo "$s" | awk -F: '{ print NF }')" -eq 3 ] || usage
done
case $RUNS in '' | *[!0-9]* | 0) usage ;; esac
case $OUT in /*) ;; *) OUT=$ROOT/$OUT ;; esac
case $BUILD in /*) ;; *) BUILD=$ROOT/$BUILD ;; esac
SIM=$BUILD/tools/simcluster
DAEMON=$BUILD/daemon/simclusterd
KMAX=$(echo "$KLIST" | awk '{ print $NF }')

QUOTA_MIN_US=1000               # the kernel's least CFS quota (cgroup v1 and v2)
LAN_MBIT=1000                   # an office LAN, scaled by the quota
LAN_DELAY_US=100                # its one-way latency, scaled by the quota (netem only)
RUN_LIMIT=900                   # s, one simcluster run at most

# shellcheck disable=SC2034 # read by bench/emulate.sh
NAME=pcs
# shellcheck source=bench/emulate.sh
. "$ROOT/bench/emulate.sh"
emu_require
tag=$$

br=scpbr$tag
CG=$CGROOT/simpcs$tag
dir=$(mktemp -d /tmp/scpcs.XXXXXX) || exit 1
pids=""

cleanup() {
    trap - EXIT INT TERM
    # shellcheck disable=SC2086 # pids: words
    emu_stop $pids
    for i in $(seq 1 "$KMAX"); do ip netns del "scp${tag}p$i" 2>/dev/null; done
    ip netns del "$br" 2>/dev/null
    for i in $(seq 1 "$KMAX"); do emu_cg_remove "$CG/p$i"; done
    [ -d "$CG" ] && rmdir "$CG"
    emu_restore
    rm -rf "$dir"
}
exec 3>&2
trap cleanup EXIT
trap 'echo "pcs: interrupted" >&3; exit 130' INT TERM
die() { echo "pcs: $*" >&2; exit 1; }

# ---- CPU: one quota for every PC ----
# The period is as short as the least quota allows, so that a PC that used
# its share stalls briefly (a real slow PC runs on instead; a stall delays a
# round trip that meets it).
ncpu=$(nproc)
share=$(awk -v n="$ncpu" -v k="$KMAX" 'BEGIN { c = 0.95 * n / k; if (c > 1) c = 1; printf "%.4f", c }')
PERIOD_US=$(awk -v s="$share" -v m=$QUOTA_MIN_US 'BEGIN { p = m / s; if (p < m) p = m
    printf "%d", p + 0.999 }')
q=$(awk -v s="$share" -v p="$PERIOD_US" -v m=$QUOTA_MIN_US 'BEGIN { q = s * p + 0.5; if (q < m) q = m
    printf "%d", q }')
share=$(awk -v q="$q" -v p="$PERIOD_US" 'BEGIN { printf "%.4f", q / p }')
mkcg() {
    emu_cg_parent "$CG" || return 1
    for i in $(seq 1 "$KMAX"); do emu_cg_child "$CG/p$i" "$q" "$PERIOD_US" || return 1; done
}
mkcg || emu_skip "cannot make cgroups with CPU quotas under $CGROOT"
if [ "$CGV" = 1 ]; then PROCS=tasks; else PROCS=cgroup.procs; fi
# in a cgroup: sh -c "$JOIN" PROCS_FILE CMD... (the shell joins, then execs)
# shellcheck disable=SC2016 # expanded by that shell
JOIN='echo $$ >"$0" && exec "$@"'
throttled() { emu_throttled "$CG/p$1"; }  # the cgroup of PC $1

# ---- network: a bridge, a shaped veth to each PC ----
RATE=$(awk -v m=$LAN_MBIT -v s="$share" 'BEGIN { printf "%dkbit", m * s * 1000 + 0.5 }')
DELAY=$(awk -v d=$LAN_DELAY_US -v s="$share" 'BEGIN { printf "%d", d / s + 0.5 }')
plumb() {
    emu_bridge "$br" || return 1
    for i in $(seq 1 "$KMAX"); do
        ns=scp${tag}p$i
        emu_node "$ns" "$br" "p$i" "10.214.35.$i" || return 1
        emu_shape "$ns" eth0 "$RATE" "$DELAY" && emu_shape "$br" "p$i" "$RATE" "$DELAY" || return 1
    done
}
plumb || die "network namespaces, bridge, veths or tc qdiscs could not be made"
emu_rmem
port=$((20000 + $(od -An -N2 -tu2 /dev/urandom) % 40000))
URL="udpm://239.255.76.67:$port?ttl=1&recv_buf_size=4194304"
KEY=$dir/key
"$SIM" keygen "$KEY" >/dev/null || die "simcluster keygen failed"
mkdir -p "$OUT/raw" || die "cannot make $OUT/raw"

# ---- daemons: PC i (2 ..) ----
start_daemon() {
    i=$1
    log=$dir/d$i.log
    : >"$log"
    sh -c "$JOIN" "$CG/p$i/$PROCS" nsenter --net="/run/netns/scp${tag}p$i" "$DAEMON" --url "$URL" \
        --key "$KEY" --threads 1 --dedicated --heartbeat 0.1 --node-id $((3500 + i)) >>"$log" 2>&1 &
    eval "dpid$i=$!"
    pids="$pids $!"
    tries=0
    while ! grep -q serving "$log"; do
        tries=$((tries + 1))
        if [ $tries -gt 200 ] || ! kill -0 "$(eval "echo \$dpid$i")" 2>/dev/null; then
            echo "pcs: daemon on PC $i did not start:" >&2
            tail -n 20 "$log" >&2
            return 1
        fi
        sleep 0.05
    done
}
stop_daemon() {
    p=$(eval "echo \$dpid$1")
    kill -TERM "$p" 2>/dev/null
    tries=0
    while kill -0 "$p" 2>/dev/null && [ $tries -lt 100 ]; do sleep 0.05; tries=$((tries + 1)); done
    kill -9 "$p" 2>/dev/null
    wait "$p" 2>/dev/null
}

# ---- one row ----
jnum() { sed -n "s/.*\"$2\": \([-0-9.e]*\).*/\1/p" "$1" | head -n 1; }
jstr() { sed -n "s/.*\"$2\": \"\([^\"]*\)\".*/\1/p" "$1" | head -n 1; }
# the ideal makespan on $2 nodes, per the run's JSON $1
jideal() { sed -n 's/.*"ideal_makespan_s": \[\([^]]*\)\].*/\1/p' "$1" | tr ',' '\n' | sed -n "${2}p" | tr -d ' '; }
run_row() { # $1 scene $2 bodies $3 frames $4 PCs: JSON in $j
    sc=$1 n=$2 fr=$3 k=$4
    j=$OUT/raw/${sc}_${n}_k$k.json
    set -- "$SIM" run "$sc" --bodies "$n" --frames "$fr" --seed 1 --workers 1 --json
    [ "$k" -gt 1 ] && set -- "$@" --cluster "$URL" --key "$KEY" --wait-daemons $((k - 1))
    r=1
    hashes=""
    while [ $r -le "$RUNS" ]; do
        if ! sh -c "$JOIN" "$CG/p1/$PROCS" timeout --foreground -k 2 $RUN_LIMIT \
            nsenter --net="/run/netns/scp${tag}p1" "$@" >"$j.r$r" 2>"$j.err" ||
            [ -z "$(jnum "$j.r$r" wall_s)" ]; then
            echo "pcs: $sc $n on $k PCs failed:" >&2
            cat "$j.err" "$j.r$r" >&2
            return 1
        fi
        hashes="$hashes $(jstr "$j.r$r" hash)"
        r=$((r + 1))
    done
    med=$(for r in $(seq 1 "$RUNS"); do echo "$(jnum "$j.r$r" wall_s) $r"; done | sort -n |
        awk -v k="$RUNS" 'NR == int((k + 1) / 2) { print $2 }')
    mv "$j.r$med" "$j"
    rm -f "$j".r* 
    [ -s "$j.err" ] || rm -f "$j.err"
    nh=$(echo "$hashes" | tr ' ' '\n' | sed '/^$/d' | sort -u | wc -l)
    [ "$nh" -eq 1 ] || HASH_VARIES=1
}

# per frame, ms: the model's T(k) from the 2-PC run's JSON $1
predict() {
    f=$(jnum "$1" frames)
    awk -v s="$(jnum "$1" serial_s)" -v w="$(jnum "$1" unit_work_s)" -v j="$(jnum "$1" jobs)" \
        -v i="$(jideal "$1" "$2")" -v o="$(jnum "$1" remote_overhead_s)" \
        -v rj="$(jnum "$1" remote_jobs)" -v f="$f" 'BEGIN {
            l = rj > 0 ? o / rj : 0
            t = i + j * l; if (w < t) t = w
            printf "%.2f", 1e3 * (s + t) / f }'
}

echo "pcs: cgroup v$CGV at $CGROOT, every PC $q us of CPU per $PERIOD_US us ($share CPU; $KMAX PCs"\
    "at most on $ncpu CPUs)"
if [ "$EMU_NETEM" = 1 ]; then
    LAT="htb at $RATE (1 Gbit/s x $share) on both ends of each PC's veth, netem delay $DELAY us under it (100 us / $share)"
else
    LAT="htb at $RATE (1 Gbit/s x $share) on both ends of each PC's veth; no netem on this kernel, so no added delay (the LAN's 100 us one way, scaled, would be $DELAY us): the latency is the 2 shaped hops' serialisation and the kernel's"
fi
echo "pcs: links: $LAT"
echo "pcs: PCs $KLIST; scenes $SCENES; median of $RUNS run(s); $URL"
t_start=$(date +%s)
MD=$OUT/pcs.md
CSV=$OUT/pcs.csv
echo "scene,bodies,pcs,ms_frame,speedup,predicted_ms,measured_over_predicted,comm_ms,same_bits" >"$CSV"
TABLES=$dir/tables
: >"$TABLES"
HASH_VARIES=0
fail=0
diffs=0
for s in $SCENES; do
    sc=${s%%:*}; rest=${s#*:}; n=${rest%%:*}; fr=${rest#*:}
    hdr=$(printf '| PCs | wall s | ms/frame | speedup | predicted ms | measured/predicted | remote %% | serial ms (%% of frame) | comm ms | msgs out/in a daemon | kB out+in a daemon | throttled s | same bits |')
    echo "pcs: $sc $n, $fr frames"
    { echo; echo "$sc of $n parts, $fr frames:"; echo; echo "$hdr"; echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"; } >>"$TABLES"
    base=""; bhash=""; calib=""
    for k in $KLIST; do
        d=2
        while [ $d -le "$k" ]; do start_daemon $d || die "daemon $d did not start"; d=$((d + 1)); done
        if [ "$k" -gt 2 ] && [ -n "$calib" ]; then
            pred=$(predict "$calib" "$k")
            echo "  $k PCs: predicted $pred ms a frame (before the run)"
        fi
        th0=$(throttled 1)
        if ! run_row "$sc" "$n" "$fr" "$k"; then fail=$((fail + 1)); k_ok=0; else k_ok=1; fi
        th1=$(throttled 1)
        d=2
        while [ $d -le "$k" ]; do stop_daemon $d; d=$((d + 1)); done
        [ $k_ok = 1 ] || continue
        [ "$k" = 2 ] && calib=$j
        wall=$(jnum "$j" wall_s); frames=$(jnum "$j" frames); h=$(jstr "$j" hash)
        [ "$k" = 1 ] && { base=$wall; bhash=$h; }
        same=$([ "$h" = "$bhash" ] && echo yes || echo NO)
        [ "$same" = yes ] || diffs=$((diffs + 1))
        if [ "$k" -ge 2 ] && [ -n "$calib" ]; then pred=$(predict "$calib" "$k"); else pred=-; fi
        row=$(awk -v w="$wall" -v f="$frames" -v b="$base" -v p="$pred" -v k="$k" \
            -v u="$(jnum "$j" units)" -v ru="$(jnum "$j" remote_units)" \
            -v se="$(jnum "$j" serial_s)" -v c="$(jnum "$j" comm_s)" \
            -v mo="$(jnum "$j" unit_messages)" -v mi="$(jnum "$j" result_messages)" \
            -v rb="$(jnum "$j" remote_bytes)" -v th="$(awk -v a="$th0" -v b="$th1" 'BEGIN { print b - a }')" \
            -v same="$same" 'BEGIN {
                ms = 1e3 * w / f; nd = 1; if (k > 1) nd = k - 1
                ratio = "-"; if (p != "-") ratio = sprintf("%.2f", ms / p)
                rs = 0; if (u > 0) rs = 100 * ru / u
                printf "| %d | %.2f | %.1f | %.2fx | %s | %s | %.1f | %.1f (%.0f %%) | %.2f | %.1f / %.1f | %.0f | %.1f | %s |", \
                    k, w, ms, b / w, p, ratio, rs, 1e3 * se / f, 100 * se / w, 1e3 * c / f, \
                    mo / f / nd, mi / f / nd, rb / f / nd / 1e3, th, same }')
        echo "$row" >>"$TABLES"
        echo "  $row"
        echo "$row" | awk -F'|' -v sc="$sc" -v n="$n" '{ gsub(/ /, ""); sub(/x$/, "", $5)
            printf "%s,%s,%s,%s,%s,%s,%s,%s,%s\n", sc, n, $2, $4, $5, $6, $7, $10, $14 }' >>"$CSV"
    done
    if [ -n "$calib" ]; then
        p16=$(predict "$calib" 16)
        t1=$(awk -v w="$base" -v f="$fr" 'BEGIN { printf "%.2f", 1e3 * w / f }')
        line="model for 16 PCs (a prediction, inputs from the 2-PC row): $p16 ms a frame, $(awk -v a="$t1" -v b="$p16" 'BEGIN { printf "%.2f", a / b }')x one PC"
        echo "  $line"
        { echo; echo "$line."; } >>"$TABLES"
    fi
done
elapsed=$(($(date +%s) - t_start))
{
    echo "## Emulated PCs: a pile shared by 1, 2, 4 and 8 PCs"
    echo
    echo "\`bench/pcs.sh -k '$KLIST' -S '$SCENES' -r $RUNS\` (as root; $(date -u '+%Y-%m-%d %H:%M UTC'), $elapsed s)."
    echo "Each PC is a network namespace with a CPU quota, the same for every PC"
    echo "and for the one-PC baseline: cgroup v$CGV, $q µs per $PERIOD_US µs ($share CPU);"
    echo "links: $LAT. PC 1 runs \`simcluster run SCENE --bodies N --frames F --seed 1"
    echo "--workers 1 --json\` (+ \`--cluster URL --key KEY --wait-daemons K-1\`), each other"
    echo "PC \`simclusterd --threads 1 --dedicated\`. The quota stalls a PC for up to"
    echo "$((PERIOD_US - q)) µs of every $PERIOD_US µs once it has used its share (\"throttled s\": the"
    echo "master's stalled time in the run); a round trip that meets a stalled end waits"
    echo "that long (the kernel applies the stall at the thread's next entry into it:"
    echo "units read the CPU clock under a quota so that it lands in their time)."
    echo "Predicted: the model of bench/pcs.sh (its header) with inputs from the 2-PC row,"
    echo "so that row's ratio shows what the model leaves out, computed before the 4- and"
    echo "8-PC rows ran."
    cat "$TABLES"
    echo
    echo "Runs whose final state differs from the one-PC run's: $diffs; runs whose repeats' hashes differed: $HASH_VARIES; failed runs: $fail."
} >"$MD"
echo "pcs: wrote $MD ($elapsed s)"
[ $fail -eq 0 ] && [ $diffs -eq 0 ]
