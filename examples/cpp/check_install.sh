#!/usr/bin/env bash
# Installs a build tree into a fresh prefix, builds examples/cpp against it with find_package,
# runs it on a simulated bin, and imports the installed Python module.
#   examples/cpp/check_install.sh BUILD_DIR
set -euo pipefail
build=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
work="$build/install-check"
rm -rf "$work"
cmake --install "$build" --prefix "$work/prefix" > /dev/null
cmake -S "$here" -B "$work/consumer" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$work/consumer" > /dev/null
"$work/prefix/bin/binpose" simulate --instances 4 --seed 4 --out "$work/bin" > /dev/null
"$work/consumer/find_caps" "$work/bin/depth.png" "$work/bin/camera.json"
module=$(find "$work/prefix/lib" -name 'binpose*.so' -path '*dist-packages*' | head -1)
if [ -n "$module" ]; then
  PYTHONPATH=$(dirname "$module") "${PYTHON:-python3}" -c "import binpose; print('python module', binpose.__version__)"
fi
