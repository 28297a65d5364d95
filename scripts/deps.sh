#!/usr/bin/env bash
# Installs binpose's build and test dependencies from Debian 12's packages (needs root or sudo).
# With --bench also the peer of the end-to-end benchmark, OpenCV's PPF detector (libopencv-contrib-dev).
set -euo pipefail
packages=(cmake ninja-build g++ pkg-config
          libeigen3-dev libnanoflann-dev libtbb-dev libcli11-dev nlohmann-json3-dev libfmt-dev
          libassimp-dev libpng-dev libtiff-dev zlib1g-dev liblzf-dev libgtest-dev libbenchmark-dev
          libbullet-dev libembree-dev gnuplot-nox
          python3-dev python3-numpy pybind11-dev python3-pytest python3-matplotlib
          clang libclang-rt-14-dev)  # clang + libFuzzer: the readers' fuzz harnesses (scripts/fuzz.sh)
[ "${1:-}" = "--bench" ] && packages+=(libopencv-dev libopencv-contrib-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
