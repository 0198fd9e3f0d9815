#!/bin/sh
# Runs every test binary of each build directory given (the normal build,
# then the ASan+UBSan one), replays the fuzz corpora, lints the man pages and
# tries an install; prints one closing line "check: N passed, M failed".
# Usage: tests/run.sh BUILD [BUILD...]
cd "$(dirname "$0")/.." || exit 1
pass=0
fail=0
failed=""
log=$(mktemp)
trap 'rm -f "$log"' EXIT

count() { # $1 = label, $2 = exit status; counts cmocka's summary lines
    p=$(sed -n 's/^\[  PASSED  \] \([0-9]*\) test.*/\1/p' "$log" | tail -n 1)
    f=$(sed -n 's/^\[  FAILED  \] \([0-9]*\) test.*/\1/p' "$log" | tail -n 1)
    p=${p:-0}
    f=${f:-0}
    if [ "$2" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi   # crashed or not cmocka
    if [ "$p" -eq 0 ] && [ "$f" -eq 0 ]; then p=1; fi   # a plain check that passed
    pass=$((pass + p))
    fail=$((fail + f))
    if [ "$f" -ne 0 ]; then
        failed="$failed $1"
        cat "$log"
    fi
}

# The cmocka binaries of every build run first, as many at once as there
# are CPUs (make check's longest part; the sanitized ones are the slowest, so
# they go first); test_cluster* and test_units run alone afterwards: the
# daemons answer within deadlines, and test_units holds each job's makespan
# to its bound, which needs a CPU for each of its threads (beside another
# test binary a unit's time holds that one's turns). Their results print
# below in build order.
runs=$(mktemp -d)
trap 'rm -f "$log"; rm -rf "$runs"' EXIT
one() { # $1 = test binary; its output, exit status and seconds into $runs
    key=$(printf '%s' "$1" | tr / _)
    start=$(date +%s)
    "$1" >"$runs/$key.log" 2>&1
    echo $? >"$runs/$key.rc"
    echo $(( $(date +%s) - start )) >"$runs/$key.s"
}
list() { # the test binaries, the last build's first; $1 = alone: only those run alone
    i=$#
    while [ "$i" -gt 1 ]; do
        eval "b=\${$i}"
        for t in "$b"/tests/test_*; do
            [ -x "$t" ] || continue
            case $(basename "$t") in
                test_cluster* | test_units) [ "$1" = alone ] && echo "$t" ;;
                *) [ "$1" = alone ] || echo "$t" ;;
            esac
        done
        i=$((i - 1))
    done
}
ncpu=$(nproc 2>/dev/null || echo 1)
for t in $(list pool "$@"); do
    while [ "$(find "$runs" -name '*.run' | wc -l)" -ge "$ncpu" ]; do sleep 0.1; done
    key=$(printf '%s' "$t" | tr / _)
    touch "$runs/$key.run"
    (one "$t"; rm -f "$runs/$key.run") &
done
wait
for t in $(list alone "$@"); do one "$t"; done

for build in "$@"; do
    echo "== tests in $build"
    for t in "$build"/tests/test_*; do
        [ -x "$t" ] || continue
        key=$(printf '%s' "$t" | tr / _)
        cp "$runs/$key.log" "$log"
        rc=$(cat "$runs/$key.rc")
        grep -E '^\[  (PASSED|FAILED)  \]' "$log" | sed "s|^|  $(basename "$t"): |"
        count "$t" "$rc"
        echo "  $(basename "$t"): $(cat "$runs/$key.s") s"
    done
    for r in "$build"/tests/fuzz/fuzz_*_replay; do
        [ -x "$r" ] || continue
        name=$(basename "$r" _replay)
        corpus=tests/fuzz/corpus/${name#fuzz_}
        "$r" "$corpus" >"$log" 2>&1
        count "$r" $?
        echo "  $(basename "$r"): $(tail -n 1 "$log")"
    done
    for t in tools view daemon top; do
        sh tests/$t.sh "$build" >"$log" 2>&1
        count "$t ($build)" $?
        echo "  $(tail -n 1 "$log")"
    done
    # the library's files call downward only, without cycles (its objects)
    sh tests/layers.sh "$build" >"$log" 2>&1
    count "layers ($build)" $?
    echo "  $(tail -n 1 "$log")"
    # daemons and a master in network namespaces: the plain build only
    # (under ASan the timings it checks do not hold)
    if [ "$build" = "$1" ]; then
        sh tests/cluster.sh "$build" >"$log" 2>&1
        count "cluster ($build)" $?
        echo "  $(tail -n 1 "$log")"
        sh tests/pcs.sh "$build" >"$log" 2>&1
        count "pcs ($build)" $?
        echo "  $(tail -n 1 "$log")"
    fi
done

echo "== static analysis (cppcheck)"
cppcheck -j "$ncpu" --quiet --error-exitcode=1 --enable=warning,performance,portability --std=c11 \
    -Iinclude -Ilib --suppress=missingIncludeSystem --inline-suppr $(ls -d lib daemon tools 2>/dev/null) >"$log" 2>&1
count cppcheck $?
echo "== man pages (mandoc -T lint)"
mandoc -T lint -W warning man/*.[1-8] >"$log" 2>&1
count mandoc $?
echo "== README (tests/readme.sh)"
sh tests/readme.sh >"$log" 2>&1
count readme $?
tail -n 1 "$log"
echo "== systemd unit (systemd-analyze verify)"
if command -v systemd-analyze >/dev/null 2>&1; then
    unit=$(mktemp -d)
    case $1 in /*) sbin=$1/daemon ;; *) sbin=$PWD/$1/daemon ;; esac
    sed "s|@SBINDIR@|$sbin|g" daemon/simclusterd.service >"$unit/simclusterd.service"
    systemd-analyze verify --man=no "$unit/simclusterd.service" >"$log" 2>&1
    rc=$?
    count "systemd unit" $rc
    rm -rf "$unit"
    [ "$rc" -eq 0 ] && echo "  simclusterd.service: verified"
else
    echo "  skipped: no systemd-analyze"
fi
echo "== install, then build examples/hello.c against the installed pkg-config"
sh tests/install.sh >"$log" 2>&1
count install $?
tail -n 3 "$log"

echo "check: $pass passed, $fail failed"
[ -n "$failed" ] && echo "failing:$failed"
[ "$fail" -eq 0 ]
