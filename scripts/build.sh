#!/usr/bin/env bash
# Configures and builds binpose. Usage: scripts/build.sh [BUILD_DIR] [extra cmake args...]
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-build}"
shift || true
mkdir -p "$dir"
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" > "$dir/cmake.log" 2>&1 || { cat "$dir/cmake.log"; exit 1; }
cmake --build "$dir" --parallel "$(nproc)"
