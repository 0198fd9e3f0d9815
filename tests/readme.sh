#!/bin/sh
# tests/readme.sh - the README says what is true: no placeholder lines, a
# tour that runs as written (the daemon stopped by its pid, the cluster run
# waiting for it, each run into its own folder), and the benchmark figures
# of bench/RESULTS.md, not older ones.
cd "$(dirname "$0")/.." || exit 1
fail=0
r=README.md
res=bench/RESULTS.md
no() { # $1 = what, $2 = a pattern README.md must not hold
    if grep -nE -- "$2" "$r"; then echo "FAIL: README: $1"; fail=1; fi
}
has() { # $1 = what, $2 = a fixed string README.md must hold
    grep -qF -- "$2" "$r" || { echo "FAIL: README: $1: no '$2'"; fail=1; }
}
no "a placeholder line" '^(XX+|TODO|TBD)$'
tour=$(sed -n '/^## A five-minute tour/,/^## /p' "$r")
echo "$tour" | grep -q 'kill %' && { echo "FAIL: README tour: kill %N stops whichever job that is"; fail=1; }
echo "$tour" | grep -q 'daemon_pid=\$!' && echo "$tour" | grep -q 'kill \$daemon_pid' ||
    { echo "FAIL: README tour: the daemon is not stopped by its pid"; fail=1; }
echo "$tour" | grep -q -- '--cluster' && ! echo "$tour" | grep -q -- '--wait-daemons 1' &&
    { echo "FAIL: README tour: the cluster run does not wait for the daemon"; fail=1; }
dirs=$(echo "$tour" | sed -n 's/.*--\(render\|out\) \([^ ]*\).*/\2/p' | sort | uniq -d)
[ -z "$dirs" ] || { echo "FAIL: README tour: two runs write into $dirs"; fail=1; }
has "ldconfig after make install" "ldconfig"
no "a machine named by 'this'" 'this 2-core (machine|VM)'
# one current figure per claim, as bench/RESULTS.md has it
rt() { sed -n "s/.*200 bodies in real time ($1.*met: \([0-9.]*\)x real time.*/\1/p" "$res" | head -n 1; }
scn=$(rt scN)
sc1=$(rt sc1)
[ -n "$scn" ] && [ -n "$sc1" ] || { echo "FAIL: $res: no 200-body real-time figures"; fail=1; }
has "200 bodies on 2 workers" "$scn× real time on 2 workers and $sc1×"
pen=$(sed -n 's/.*200 bodies, scN: penetration.*: \([0-9]*\)\.[0-9]* mm (.*/\1/p' "$res" | head -n 1)
has "200-body penetration" "200 bodies: $pen mm"
no "an older penetration figure" '200 bodies: up to [0-9]+ mm'
best=$(sed -n 's/.*best in this run \([0-9.]*\)x with 1 daemon.*/\1/p' "$res" | head -n 1)
has "speedup with 1 daemon" "| $best× |"
has "speedup with 1 daemon" "1 daemon
  on the 2-core VM: $best×"
# the slowdown with its sign (a figure within the noise can be negative)
fg=$(sed -n 's/.*slows a CPU-bound foreground program.* met[^:]*: \([+-][0-9.]*\) %.*/\1/p' "$res" | head -n 1)
has "cycle stealing" "runs $fg % slower"
has "cycle stealing" "foreground slowdown $fg %"
[ "$fail" -eq 0 ] && echo "readme: all checks passed"
exit "$fail"
