#!/usr/bin/env bash
# The test command: installs dependencies, builds, runs every unit test (Release), then again
# under AddressSanitizer + UndefinedBehaviorSanitizer, then fuzzes each file reader for a minute
# (scripts/fuzz.sh). Needs ../shared/data beside the repo.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
echo "== Release build and tests"
scripts/build.sh build
ctest --test-dir build --output-on-failure -j "$(nproc)"
echo "== ASan + UBSan build and tests"
scripts/build.sh build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBINPOSE_SANITIZE=ON -DBINPOSE_BUILD_BENCH=OFF -DBINPOSE_BUILD_PYTHON=OFF
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure -j "$(nproc)"
echo "== Fuzzing the readers (libFuzzer, the six harnesses side by side for 60 s)"
FUZZ_JOBS=6 scripts/fuzz.sh 60
