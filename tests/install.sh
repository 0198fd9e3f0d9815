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
# the network header: installed, needing only the C library's headers and
# simcluster.h (no LCM, no libsodium), and usable with the same flags
inc="$d/usr/local/include"
test -f "$inc/simcluster_net.h"
other=$(grep -h '^#include' "$inc/simcluster.h" "$inc/simcluster_net.h" |
        grep -v -e '<stddef.h>' -e '<stdint.h>' -e '"simcluster.h"' || true)
if [ -n "$other" ]; then echo "public headers include: $other"; exit 1; fi
cat >"$d/net.c" <<'EOF'
#include <stdio.h>
#include <stdlib.h>
#include <simcluster_net.h>

int main(void)
{
    sc_world *w = sc_world_create(NULL);
    sc_shape *ball = sc_shape_sphere(0.1);
    sc_body_desc b = sc_body_desc_default();
    b.shape = ball;
    if (!w || !ball || sc_body_add(w, &b) != 0)
        return 1;
    sc_frame_record r = { 0 }, back = { 0 };
    uint8_t *buf;
    size_t len;
    int ok = sc_frame_record_capture(&r, w, 0, 0) == SC_OK &&
             sc_frame_record_encode(&r, &buf, &len) == SC_OK &&
             sc_frame_record_decode(buf, len, &back) == SC_OK && back.n == 1 &&
             back.shape[0] == sc_shape_hash(ball);
    printf("frame record of one body: %zu bytes\n", ok ? len : 0);
    sc_frame_record_free(&r);
    sc_frame_record_free(&back);
    if (ok)
        free(buf);
    sc_shape_release(ball);
    sc_world_destroy(w);
    return !ok;
}
EOF
cc -std=c11 -Wall -Wextra -Werror "$d/net.c" -o "$d/net" $flags
LD_LIBRARY_PATH="$d/usr/local/lib" "$d/net"
# the README's first program, built and run exactly as the README shows
# it against a library installed under $HOME/sc (HOME here a scratch
# folder): the rpath build, the LD_LIBRARY_PATH run, the static build
home="$d/home"
mkdir -p "$home"
MAKEFLAGS= make --no-print-directory install PREFIX="$home/sc" >/dev/null
awk '/^## A first program/ { s = 1; next } s && /^## / { exit }
     s && /^```c$/ { f = 1; next } f && /^```$/ { exit } f' README.md >"$home/first.c"
grep -q 'int main' "$home/first.c" || { echo "README: no first program"; exit 1; }
# its sh blocks after the first (which needs a system-wide install)
awk '/^## A first program/ { s = 1; next } s && /^## / { exit }
     s && /^```sh$/ { n++; f = n > 1; next } /^```$/ { f = 0 } f' README.md >"$home/build.sh"
grep -q 'rpath' "$home/build.sh" && grep -q -- '--static' "$home/build.sh" ||
    { echo "README: no rpath or static build of the first program"; exit 1; }
(cd "$home" && HOME="$home" sh -e build.sh >"$home/shown.out")
grep -q '^box at rest: z = 0\.09[0-9]* m, state 3$' "$home/shown.out" ||
    { echo "README first program: $(cat "$home/shown.out")"; exit 1; }
# the last build is the static one: it runs with no libsimcluster.so
if ldd "$home/first" | grep -q simcluster; then echo "README static build links the .so"; exit 1; fi
(cd "$home" && ./first) | grep -q '^box at rest' || { echo "README static build does not run"; exit 1; }
MAKEFLAGS= make --no-print-directory uninstall PREFIX="$home/sc" >/dev/null
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
