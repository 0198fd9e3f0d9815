#!/bin/sh
# tests/tools.sh BUILD - the command-line tools as a user meets them: exit
# statuses, one-line errors, the files they write.
tool="$1/tools/simcluster"
dir=$(mktemp -d) || exit 1
trap 'rm -rf "$dir"' EXIT
fail=0
check() { # $1 = what, $2 = expected status, then the command
    what=$1; want=$2; shift 2
    "$@" >"$dir/out" 2>"$dir/err"
    got=$?
    if [ "$got" -ne "$want" ]; then
        echo "FAIL: $what: exit $got, expected $want"; cat "$dir/err"; fail=1
    fi
}
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
check "no command" 2 "$tool"
check "unknown command" 2 "$tool" frobnicate
check "--help" 0 "$tool" --help
grep -q keygen "$dir/out" || { echo "FAIL: --help does not list keygen"; fail=1; }
[ "$fail" -eq 0 ] && echo "tools: all checks passed"
exit "$fail"
