#!/bin/sh
# The library's files call each other in one direction only: from the
# objects' symbols (nm), every call between two files of lib/ goes to the
# same or a lower layer (core <- exec <- net <- api), and the calls between
# files have no cycle (tsort). docs/DESIGN.md section 2.
# Usage: tests/layers.sh BUILD
build=${1:-build}
cd "$(dirname "$0")/.." || exit 1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rank() { case $1 in core/*) echo 1 ;; exec/*) echo 2 ;; net/*) echo 3 ;; api/*) echo 4 ;; *) echo 9 ;; esac; }
# the objects of the sources there are now (a build folder may keep the
# objects of files since moved away)
for src in lib/*/*.c; do
    o=$build/${src%.c}.o
    [ -f "$o" ] || { echo "FAIL: no object $o (build first)"; exit 1; }
    f=${src#lib/}
    f=${f%.c}
    nm --defined-only -g "$o" | awk -v f="$f" 'NF == 3 { print $3, f }' >>"$tmp/defs"
    nm -u "$o" | awk -v f="$f" '{ print $2, f }' >>"$tmp/uses"
done
sort -u "$tmp/defs" >"$tmp/defs.s"
sort -u "$tmp/uses" >"$tmp/uses.s"
# user provider, for every symbol a file uses that another file defines
join "$tmp/uses.s" "$tmp/defs.s" | awk '$2 != $3 { print $2, $3 }' | sort -u >"$tmp/edges"
fail=0
edges=$(wc -l <"$tmp/edges")
while read -r user prov; do
    if [ "$(rank "$user")" -lt "$(rank "$prov")" ]; then
        echo "FAIL: $user calls up into $prov"
        fail=1
    fi
done <"$tmp/edges"
if ! tsort "$tmp/edges" >/dev/null 2>"$tmp/loop"; then
    echo "FAIL: the calls between files have a cycle:"
    cat "$tmp/loop"
    fail=1
fi
[ "$edges" -gt 20 ] || { echo "FAIL: only $edges calls between files found"; fail=1; }
if [ "$fail" -eq 0 ]; then
    echo "layers: $edges calls between files, all downward or within a layer, no cycle"
else
    echo "layers: failed"
fi
exit $fail
