#!/bin/sh
# tests/pcs.sh BUILD - bench/pcs.sh's smoke run (-q: a bin of 200 on 1 and 2
# emulated PCs): it must end with both rows, the same bits in each, and a
# prediction on the 2-PC row; or say SKIPPED (not root, no namespaces, tc or
# cgroup CPU controller). Prints one closing line.
cd "$(dirname "$0")/.." || exit 1
build=${1:-build}
out=$(mktemp -d) || exit 1
trap 'rm -rf "$out"' EXIT
if ! sh bench/pcs.sh -q -b "$build" -o "$out" >"$out/log" 2>&1; then
    cat "$out/log"
    echo "pcs: FAIL (bench/pcs.sh -q failed)"
    exit 1
fi
if grep -q '^pcs: SKIPPED' "$out/log"; then
    echo "pcs: $(grep '^pcs: SKIPPED' "$out/log" | sed 's/^pcs: //')"
    exit 0
fi
csv=$out/pcs.csv
# scene,bodies,pcs,ms_frame,speedup,predicted_ms,measured_over_predicted,comm_ms,same_bits
rows=$(awk -F, 'NR > 1' "$csv" | wc -l)
same=$(awk -F, 'NR > 1 && $9 == "yes"' "$csv" | wc -l)
pred=$(awk -F, 'NR > 1 && $3 == 2 && $6 != "-" && $6 + 0 > 0' "$csv" | wc -l)
if [ "$rows" -ne 2 ] || [ "$same" -ne 2 ] || [ "$pred" -ne 1 ] || [ ! -s "$out/pcs.md" ]; then
    cat "$out/log" "$csv"
    echo "pcs: FAIL ($rows rows, $same with the same bits, $pred predicted)"
    exit 1
fi
echo "pcs: 1 and 2 emulated PCs, the same bits, the 2-PC row predicted"
