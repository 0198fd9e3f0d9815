# bench/emulate.sh - sourced by bench/figs34.sh and bench/pcs.sh, which
# emulate PCs on this machine (POSIX sh): the checks both make first, and
# the cgroups, namespaces, shaped links and cleanup both build with. The
# sourcing script sets NAME (its prefix), SIM and DAEMON.

# emu_skip WHY: say SKIPPED and end the script well (no root, namespaces...)
emu_skip() { echo "$NAME: SKIPPED ($1)"; exit 0; }

# emu_require: root, iproute2's ip and tc, network namespaces that nsenter
# can enter, a cgroup CPU controller (sets CGV to 1 or 2 and CGROOT; v1 if
# the cpu controller is mounted as such, else v2), and the built programs.
emu_require() {
    [ "$(id -u)" -eq 0 ] || emu_skip "needs root"
    command -v ip >/dev/null 2>&1 || emu_skip "no ip (iproute2)"
    command -v tc >/dev/null 2>&1 || emu_skip "no tc (iproute2)"
    probe="${NAME}probe$$"
    ip netns add "$probe" 2>/dev/null || emu_skip "no network namespaces"
    ip netns exec "$probe" true 2>/dev/null && command -v nsenter >/dev/null
    ok=$?
    ip netns del "$probe"
    [ "$ok" -eq 0 ] || emu_skip "no network namespaces"
    CGV=""
    if [ -f /sys/fs/cgroup/cpu/cpu.cfs_quota_us ]; then
        CGV=1
        CGROOT=/sys/fs/cgroup/cpu
    else
        CGROOT=$(awk '$3 == "cgroup2" { print $2; exit }' /proc/mounts)
        [ -n "$CGROOT" ] && grep -qw cpu "$CGROOT/cgroup.controllers" 2>/dev/null && CGV=2
    fi
    [ -n "$CGV" ] || emu_skip "no cgroup cpu controller"
    for b in "$SIM" "$DAEMON"; do
        [ -x "$b" ] || { echo "$NAME: $b missing (run make first)" >&2; exit 1; }
    done
}

# emu_throttled DIR: the throttled time so far of the cgroup at DIR, s
emu_throttled() {
    if [ "$CGV" = 1 ]; then
        awk '$1 == "throttled_time" { printf "%.3f", $2 / 1e9 }' "$1/cpu.stat"
    else
        awk '$1 == "throttled_usec" { printf "%.3f", $2 / 1e6 }' "$1/cpu.stat"
    fi
}

# ---- cgroups ----

# emu_cg_parent DIR: the cgroup that holds the PCs' (v2: the cpu controller
# given to its children, and to it where its parent did not give it yet:
# EMU_SUBTREE_ADDED=1, which emu_restore takes back)
EMU_SUBTREE_ADDED=""
emu_cg_parent() {
    mkdir "$1" || return 1
    if [ "$CGV" = 2 ]; then
        if ! grep -qw cpu "$CGROOT/cgroup.subtree_control"; then
            echo "+cpu" >"$CGROOT/cgroup.subtree_control" || return 1
            EMU_SUBTREE_ADDED=1
        fi
        echo "+cpu" >"$1/cgroup.subtree_control" || return 1
    fi
}

# emu_cg_child DIR QUOTA_US PERIOD_US: a PC's cgroup with its CPU quota
emu_cg_child() {
    mkdir "$1" || return 1
    if [ "$CGV" = 1 ]; then
        echo "$3" >"$1/cpu.cfs_period_us" && echo "$2" >"$1/cpu.cfs_quota_us"
    else
        echo "$2 $3" >"$1/cpu.max"
    fi
}

# emu_cg_remove DIR: what is still in the cgroup (started by the script)
# killed, then the cgroup removed
emu_cg_remove() {
    [ -f "$1/cgroup.procs" ] || return 0
    while read -r p; do kill -9 "$p" 2>/dev/null; done <"$1/cgroup.procs"
    tries=0
    while [ -s "$1/cgroup.procs" ] && [ $tries -lt 50 ]; do
        sleep 0.1
        tries=$((tries + 1))
    done
    rmdir "$1"
}

# ---- network ----

# emu_bridge NS: a namespace with a bridge br0 that floods multicast to
# every port (a switch without IGMP snooping)
emu_bridge() {
    ip netns add "$1" && ip -n "$1" link set lo up &&
        ip -n "$1" link add br0 type bridge mcast_snooping 0 && ip -n "$1" link set br0 up
}

# emu_node NS BR PORT ADDR: a PC's namespace NS, its eth0 (ADDR/24, the
# multicast route) a veth to port PORT of BR's bridge
emu_node() {
    ip netns add "$1" && ip -n "$1" link set lo up &&
        ip -n "$2" link add "$3" type veth peer name eth0 netns "$1" &&
        ip -n "$2" link set "$3" master br0 && ip -n "$2" link set "$3" up &&
        ip -n "$1" addr add "$4/24" dev eth0 && ip -n "$1" link set eth0 up &&
        ip -n "$1" route add 224.0.0.0/4 dev eth0
}

# emu_shape NS DEV RATE DELAY_US: DEV of NS shaped by htb at RATE with a
# netem delay under it; where the kernel has no netem (found on the first
# call: EMU_NETEM=0) a plain fifo, and no delay beyond the store-and-forward
# of each shaped hop
EMU_NETEM=""
emu_shape() {
    tc -n "$1" qdisc add dev "$2" root handle 1: htb default 1 &&
        tc -n "$1" class add dev "$2" parent 1: classid 1:1 htb rate "$3" ceil "$3" \
            quantum 1514 || return 1
    if [ "$EMU_NETEM" != 0 ] && ! tc -n "$1" qdisc add dev "$2" parent 1:1 handle 10: \
        netem delay "${4}us" limit 10000 2>/dev/null; then
        [ -z "$EMU_NETEM" ] || return 1
        EMU_NETEM=0
    fi
    [ -n "$EMU_NETEM" ] || EMU_NETEM=1
    if [ "$EMU_NETEM" = 0 ]; then
        tc -n "$1" qdisc add dev "$2" parent 1:1 handle 10: pfifo limit 10000 || return 1
    fi
}

# emu_rmem: net.core.rmem_max (one value for every namespace) at least
# 4 MiB, for the daemons' receive buffers; emu_restore puts it back
EMU_RMEM_OLD=""
emu_rmem() {
    rmem=$(cat /proc/sys/net/core/rmem_max)
    if [ "$rmem" -lt 4194304 ]; then
        EMU_RMEM_OLD=$rmem
        echo 4194304 >/proc/sys/net/core/rmem_max
    fi
}

# emu_restore: what emu_cg_parent and emu_rmem changed outside the script's own
emu_restore() {
    [ -n "$EMU_SUBTREE_ADDED" ] && echo "-cpu" >"$CGROOT/cgroup.subtree_control" 2>/dev/null
    [ -n "$EMU_RMEM_OLD" ] && echo "$EMU_RMEM_OLD" >/proc/sys/net/core/rmem_max
    return 0
}

# emu_stop PIDS...: the script's programs asked to stop (TERM: timeout(1)
# passes it on), then killed, then reaped
emu_stop() {
    for p in "$@"; do kill "$p" 2>/dev/null; done
    sleep 0.3
    for p in "$@"; do kill -9 "$p" 2>/dev/null; done
    wait 2>/dev/null
}
