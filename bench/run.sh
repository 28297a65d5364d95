#!/usr/bin/env bash
# End-to-end benchmark: installs the peer (OpenCV's PPF detector), builds, simulates the seeded
# bins once into out/bench/, runs binpose and OpenCV on every input and writes the table to the
# terminal and to bench/results.json. Arguments go to binpose_bench_e2e (e.g. --repeats 3,
# --inputs cap-16,ipd8-16, --methods binpose,opencv-sample). Then the stage micro-benchmarks.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh --bench
scripts/build.sh build > /dev/null
build/bench/binpose_bench_e2e --data ../shared/data --cache out/bench --out bench/results.json "$@"
echo; echo "== stage micro-benchmarks (median of 5)"
build/bench/binpose_bench_stages --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
  --benchmark_out=bench/stages.json --benchmark_out_format=json 2>&1 | grep -E "median|^Run|CPU|Benchmark"
