#!/bin/sh
# tests/readme.sh - the README is a user's guide that says what is true: at
# most 300 lines, no placeholder lines, no dated history outside its one
# table of figures, a tour that runs as written (the daemon stopped by its
# pid, the cluster run waiting for it, each run into its own folder), and
# the figures of bench/RESULTS.md with the date of that run. (The first
# program is built and run as shown by tests/install.sh.)
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
n=$(wc -l <"$r")
[ "$n" -le 300 ] || { echo "FAIL: README: $n lines, at most 300"; fail=1; }
no "a placeholder line" '^(XX+|TODO|TBD|TABLE)$'
# dates and times only in the table of figures (its lines start with |)
if grep -nE '(20[0-9]{2}-[01][0-9]-[0-3][0-9]|UTC)' "$r" | grep -vE '^[0-9]+:\|'; then
    echo "FAIL: README: a date outside the table of figures"; fail=1
fi
tour=$(sed -n '/^## The command line/,/^## /p' "$r")
[ -n "$tour" ] || { echo "FAIL: README: no command-line tour"; fail=1; }
echo "$tour" | grep -q 'kill %' && { echo "FAIL: README tour: kill %N stops whichever job that is"; fail=1; }
echo "$tour" | grep -q 'daemon_pid=\$!' && echo "$tour" | grep -q 'kill \$daemon_pid' ||
    { echo "FAIL: README tour: the daemon is not stopped by its pid"; fail=1; }
echo "$tour" | grep -q -- '--cluster' && ! echo "$tour" | grep -q -- '--wait-daemons 1' &&
    { echo "FAIL: README tour: the cluster run does not wait for the daemon"; fail=1; }
dirs=$(echo "$tour" | sed -n 's/.*--\(render\|out\) \([^ ]*\).*/\2/p' | sort | uniq -d)
[ -z "$dirs" ] || { echo "FAIL: README tour: two runs write into $dirs"; fail=1; }
has "ldconfig after make install" "ldconfig"
has "a non-system install" "LD_LIBRARY_PATH"
has "the static library" "pkg-config --static"
no "a machine named by 'this'" 'this 2-core (machine|VM)'
# the table of figures: the run's date, and each figure as RESULTS.md has it
date=$(sed -n 's/^| date | \([0-9-]* [0-9:]* UTC\),.*/\1/p' "$res" | head -n 1)
[ -n "$date" ] || { echo "FAIL: $res: no date"; fail=1; }
has "the date of the figures' run" "$date"
fig() { # $1 = what, $2 = a sed pattern whose \1 is the figure in RESULTS.md, $3 = README's form of it
    v=$(sed -n "s/$2/\1/p" "$res" | head -n 1)
    if [ -z "$v" ]; then echo "FAIL: $res: no figure for $1"; fail=1; return; fi
    has "$1" "$(printf "$3" "$v")"
}
fig "200 bodies, 2 workers" '.*200 bodies in real time (scN.*met: \([0-9.]*\)x real time.*' '| %s× real time on 2 workers'
fig "200 bodies, 1 worker" '.*200 bodies in real time (sc1.*met: \([0-9.]*\)x real time.*' '%s× on one |'
fig "the pile against QuickStep" '.*200-part pile, slN, 2 threads: real-time factor >= QuickStep.s (goal.*: \([0-9.]*\)x QuickStep.*' '| %s× ODE QuickStep'
fig "the pile's penetration" '.*200-part pile, slN, 2 threads: max penetration.*: \([0-9.]*\) mm.*' '%s mm deepest'
fig "the bin of 1000 over 10 s, 1 thread" '.*bin of 1000, 10 s, 1 thread: real-time factor.*: \([0-9.]*\)x QuickStep.*' '| %s× QuickStep'"'"'s speed on one worker'
fig "the bin of 1000 over 10 s, 2 threads" '.*bin of 1000, 10 s, [0-9]* threads: real-time factor.*: \([0-9.]*\)x QuickStep.*' '%s× on 2 |'
fig "the bin of 1000 over 2 s, 1 thread" '.*bin of 1000, 2 s, 1 thread: real-time factor.*: \([0-9.]*\)x QuickStep.*' '| %s× QuickStep'"'"'s speed on one worker'
fig "the bin of 1000 over 2 s, 2 threads" '.*bin of 1000, 2 s, [0-9]* threads: real-time factor.*: \([0-9.]*\)x QuickStep.*' '%s× on 2 |'
fig "canonical scenes" '.*(j) canonical scenes.*— \(.*\)$' '| %s |'
fig "Table 1 energy" '.*(a) energy of the e = 1 sphere scene.*worst drift \([0-9.]*\) %.*' '| within %s %% |'
fig "one daemon" '.*best in this run \([0-9.]*\)x with 1 daemon.*' '| %s× one worker'
fig "emulated PCs" '.*bin 1000 on 8 PCs \([0-9.]*\)x.*' '| %s× one PC |'
fig "cycle stealing" '.*slows a CPU-bound foreground program.* met[^:]*: \([+-][0-9.]*\) %.*' '| %s %% |'
[ "$fail" -eq 0 ] && echo "readme: all checks passed"
exit "$fail"
