#!/bin/sh
# Checks the Debian packages simcluster builds and tests with. As root it
# installs the missing ones (apt-get update first); otherwise it prints the
# exact install line and fails.
#   scripts/deps.sh         what make, make check and make demo need
#   scripts/deps.sh bench   what the benchmark scripts need besides
#                           (bench/figs34.sh: gnuplot, ip and tc)
#   scripts/deps.sh video   what simcluster-view --mp4 needs besides (ffmpeg)
PKGS="build-essential pkg-config libode-dev libccd-dev liblcm-dev liblcm-bin libglib2.0-dev \
libgsl-dev libsodium-dev libsuitesparse-dev libcmocka-dev libosmesa6-dev libpng-dev mandoc cppcheck"
BENCH_PKGS="gnuplot-nox iproute2"
VIDEO_PKGS="ffmpeg"
case ${1:-} in
"") ;;
bench) PKGS=$BENCH_PKGS ;;
video) PKGS=$VIDEO_PKGS ;;
*) echo "usage: scripts/deps.sh [bench|video]" >&2; exit 2 ;;
esac
missing=""
for p in $PKGS; do
    st=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null)
    case "$st" in *" installed") ;; *) missing="$missing $p" ;; esac
done
[ -z "$missing" ] && exit 0
if [ "$(id -u)" = 0 ]; then
    echo "deps: installing:$missing"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q && apt-get install -y -q --no-install-recommends $missing && exit 0
    echo "deps: apt-get failed" >&2
    exit 1
fi
echo "deps: missing Debian packages. Install them with:" >&2
echo "  sudo apt-get update && sudo apt-get install -y$missing" >&2
exit 1
