#!/bin/sh
# Fuzzes every tests/fuzz/fuzz_*.c with libFuzzer (clang, ASan + UBSan) for
# SECONDS on its corpus tests/fuzz/corpus/NAME/, then merges the inputs that
# reach new edges back into that corpus (-merge=1 -use_counters=0: hit-count
# buckets alone would add hundreds of files a run). Crashes, leaks and
# timeouts are written to tests/fuzz/findings/ (ignored by git); once fixed,
# each goes into the corpus so make check replays it.
# Usage: tests/fuzz/run.sh [SECONDS]          (make fuzz FUZZ_TIME=SECONDS)
# Environment: FUZZ_BUILD  where binaries go (default build/fuzz)
#              CLANG       compiler (default clang)
#              FUZZ_MINIMIZE=1  re-minimise the whole corpus; files with
#                          hand-given names (seeds, fixed crashes) are kept
#              FUZZ_EXTRA_SRC   more sources to link (stand-ins for a
#                          library file that is not written yet)
set -eu
cd "$(dirname "$0")/../.."
secs=${1:-60}
out=${FUZZ_BUILD:-build/fuzz}
cc=${CLANG:-clang}
findings=tests/fuzz/findings
flags="-std=c11 -D_GNU_SOURCE -Iinclude -Ilib -Ilib/core -Ilib/exec -Ilib/net -Ilib/api -I$out/gen -O1 -g -fno-omit-frame-pointer -pthread
       -fsanitize=address,undefined -fno-sanitize-recover=all"
libs=$(pkg-config --libs ode ccd gsl lcm libsodium 2>/dev/null ||
       echo -lode -lccd -lgsl -lgslcblas -llcm -lsodium)
mkdir -p "$out/obj" "$out/gen" "$findings"
rm -f "$out"/gen/sclcm_*
lcm-gen -c --c-no-pubsub --c-cpath "$out/gen" --c-hpath "$out/gen" proto/*.lcm

# Keywords libFuzzer cannot easily guess, per target (name after fuzz_).
dict_load() {
    cat <<'EOF'
"solid "
"endsolid"
"facet normal "
"outer loop"
"vertex "
"endloop"
"endfacet"
"v "
"f "
"vn "
"vt "
"/"
"//"
"#"
"\x0d\x0a"
"-1"
"-0"
"1e308"
"1e-320"
".5"
EOF
}

dict_scene() {
    for k in gravity tolerance material shape body density restitution friction sphere box \
             plane uvsphere bolt nut mesh hull scale static mass pos quat rot vel omega grid; do
        printf '"%s"\n' "$k"
    done
    printf '"\\x0a"\n"#"\n"\\x22"\n"1e308"\n"-0"\n'
}

# The library, instrumented for coverage, as an archive: each target links
# only the objects it needs.
objs=""
for src in lib/*/*.c "$out"/gen/sclcm_*.c; do
    o="$out/obj/$(basename "$src" .c).o"
    $cc $flags -fsanitize=fuzzer-no-link -c "$src" -o "$o"
    objs="$objs $o"
done
rm -f "$out/libsimcluster_fuzz.a"
ar rcs "$out/libsimcluster_fuzz.a" $objs

status=0
merge="-merge=1 -use_counters=0 -max_len=65536 -timeout=10"
for src in tests/fuzz/fuzz_*.c; do
    name=$(basename "$src" .c)
    short=${name#fuzz_}
    corpus=tests/fuzz/corpus/$short
    bin=$out/$name
    $cc $flags -fsanitize=fuzzer "$src" ${FUZZ_EXTRA_SRC:-} "$out/libsimcluster_fuzz.a" \
        -o "$bin" $libs -lm
    new=$out/$name.new
    rm -rf "$new"
    mkdir -p "$new" "$corpus"
    dict=""
    if command -v "dict_$short" >/dev/null 2>&1; then
        "dict_$short" >"$out/$short.dict"
        dict="-dict=$out/$short.dict"
    fi
    echo "== $name: fuzzing for $secs s on $corpus"
    # new inputs go to the first directory, the corpus only seeds the run
    "$bin" -max_len=65536 -timeout=10 -rss_limit_mb=2048 -max_total_time="$secs" \
        -print_final_stats=1 -artifact_prefix="$findings/$name-" $dict \
        "$new" "$corpus" || { status=1; echo "== $name: FAILED, see $findings/"; }
    if [ "${FUZZ_MINIMIZE:-0}" = 1 ]; then
        min=$out/$name.min
        rm -rf "$min"
        mkdir -p "$min"
        for f in "$corpus"/*; do        # keep all but libFuzzer's SHA-1 names
            base=${f##*/}
            case $base in
            *[!0-9a-f]*) cp "$f" "$min" ;;
            *) [ ${#base} -eq 40 ] || cp "$f" "$min" ;;
            esac
        done
        "$bin" $merge "$min" "$corpus" "$new" 2>"$out/$name.merge.log"
        rm -f "$corpus"/*
        cp "$min"/* "$corpus"/
    else
        "$bin" $merge "$corpus" "$new" 2>"$out/$name.merge.log"
    fi
    echo "== $name: corpus now $(ls "$corpus" | wc -l) files, $(du -sk "$corpus" | cut -f1) KiB"
done
exit $status
