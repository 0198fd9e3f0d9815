# tests/cli_lib.sh - what the command-line tests (tools.sh, daemon.sh,
# top.sh) share; sourced after they set $dir (a scratch directory), $fail
# (0) and, for wait_log, $pid (the daemon) with its log in $dir/log.
check() { # $1 = what, $2 = expected status, then the command
    what=$1; want=$2; shift 2
    "$@" >"$dir/out" 2>"$dir/err"
    got=$?
    if [ "$got" -ne "$want" ]; then
        echo "FAIL: $what: exit $got, expected $want"; cat "$dir/err"; fail=1
    fi
}
one_line() { # $1 = what, $2 = a pattern the line holds
    if [ "$(wc -l <"$dir/err")" -ne 1 ] || ! grep -q -- "$2" "$dir/err"; then
        echo "FAIL: $1: expected one line with '$2'"; cat "$dir/err"; fail=1
    fi
}
# Wait up to 10 s for a line matching $1 in the daemon's log.
wait_log() {
    i=0
    while ! grep -q -- "$1" "$dir/log"; do
        i=$((i + 1))
        if [ "$i" -gt 100 ] || ! kill -0 "$pid" 2>/dev/null; then
            echo "FAIL: no log line '$1'"; cat "$dir/log"; fail=1; return 1
        fi
        sleep 0.1
    done
}
