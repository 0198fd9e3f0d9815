# bench/emulate.sh - sourced by bench/figs34.sh and bench/pcs.sh, which
# emulate PCs on this machine (POSIX sh): what both need before they build
# anything. The sourcing script sets NAME (its prefix), SIM and DAEMON.

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
