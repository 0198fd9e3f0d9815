#!/bin/sh
# make install into a temporary DESTDIR, then compile and run examples/hello.c
# with nothing but the installed header, library and pkg-config file.
set -e
cd "$(dirname "$0")/.."
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
MAKEFLAGS= make --no-print-directory install PREFIX=/usr/local DESTDIR="$d" >/dev/null
pc="$d/usr/local/lib/pkgconfig"
test -f "$pc/simcluster.pc"
flags=$(PKG_CONFIG_PATH="$pc" pkg-config --define-variable=prefix="$d/usr/local" --cflags --libs simcluster)
cc -std=c11 -Wall -Wextra -Werror examples/hello.c -o "$d/hello" $flags
LD_LIBRARY_PATH="$d/usr/local/lib" "$d/hello" >"$d/hello.out"
cat "$d/hello.out"
# it shows the drop: the first bounce reaches e^2 = 1/4 of the 0.9 m fall
# (225 mm; 10 ms frames near the top: within 5 mm), and the ball sleeps
first=$(sed -n 's/.*bounced up to .* (\([0-9.]*\) mm above the floor)$/\1/p' "$d/hello.out" | head -n 1)
awk -v h="$first" 'BEGIN { exit !(h > 220 && h < 230) }' ||
    { echo "hello: first bounce '$first' mm, expected 225"; exit 1; }
tail -n 1 "$d/hello.out" | grep -q "ball asleep" || { echo "hello: the ball does not sleep"; exit 1; }
# only sc_* symbols leave the shared library
bad=$(nm -D --defined-only "$d/usr/local/lib/libsimcluster.so" | awk '$2 ~ /[TDBR]/ {print $3}' | grep -v '^sc_' || true)
if [ -n "$bad" ]; then echo "exported non-sc_ symbols: $bad"; exit 1; fi
readelf -d "$d/usr/local/lib/libsimcluster.so" | grep -q 'SONAME.*libsimcluster.so.0'
# the tools with their pages, and the daemon's systemd unit naming where it went
for f in bin/simcluster bin/simcluster-top sbin/simclusterd share/man/man1/simcluster-top.1 \
         share/man/man8/simclusterd.8 lib/systemd/system/simclusterd.service; do
    test -f "$d/usr/local/$f" || { echo "not installed: $f"; exit 1; }
done
grep -qx 'ExecStart=/usr/local/sbin/simclusterd .*' "$d/usr/local/lib/systemd/system/simclusterd.service"
MAKEFLAGS= make --no-print-directory uninstall PREFIX=/usr/local DESTDIR="$d" >/dev/null
left=$(find "$d/usr/local" -type f)
if [ -n "$left" ]; then echo "left after uninstall: $left"; exit 1; fi
# -Werror only where asked (make check, CI): a plain make or make install
# must not fail on a newer compiler's new warning
MAKEFLAGS= make --no-print-directory -n -B V=1 build/lib/core/error.o | grep -q -- -Werror &&
    { echo "a plain make compiles with -Werror"; exit 1; }
MAKEFLAGS= make --no-print-directory -n -B V=1 WERROR=-Werror build/lib/core/error.o | grep -q -- -Werror ||
    { echo "make WERROR=-Werror compiles without -Werror"; exit 1; }
grep -q 'MAKE).*WERROR=-Werror all' Makefile && grep -q 'MAKE).*WERROR=-Werror SAN=1' Makefile ||
    { echo "make check does not build with -Werror"; exit 1; }
echo "install test: ok"
