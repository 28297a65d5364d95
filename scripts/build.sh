#!/usr/bin/env bash
# Configures and builds binpose. Usage: scripts/build.sh [BUILD_DIR] [extra cmake args...]
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-build}"
shift || true
mkdir -p "$dir"
# The Python module is built for the system's python3 (where Debian's numpy is).
python=(); [ -x /usr/bin/python3 ] && python=(-DPython_EXECUTABLE=/usr/bin/python3)
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${python[@]}" "$@" > "$dir/cmake.log" 2>&1 || { cat "$dir/cmake.log"; exit 1; }
cmake --build "$dir" --parallel "$(nproc)"
