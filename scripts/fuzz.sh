#!/usr/bin/env bash
# Fuzzes binpose's readers with libFuzzer (clang, ASan + UBSan with float-cast-overflow).
#   scripts/fuzz.sh [SECONDS per harness, default 60] [HARNESS ...]   (ply pcd depth mesh bpdb xyz)
# Builds tests/fuzz into build-fuzz, seeds a working corpus per harness from tests/fuzz/corpus
# and the heads of ../shared/data's real files, then runs the harnesses FUZZ_JOBS at a time
# (default 2; the test command runs all six side by side). A crash,
# leak, timeout (> 10 s) or out-of-memory (> 2 GB) fails the script; libFuzzer writes the input
# to build-fuzz/findings/. Needs clang and libclang-rt-14-dev (scripts/deps.sh --fuzz).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
harnesses=("$@")
[ ${#harnesses[@]} -eq 0 ] && harnesses=(ply pcd depth mesh bpdb xyz)

cmake -S tests/fuzz -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++ >/dev/null
cmake --build build-fuzz

# Heads of real files (header and first points: the fuzzer mutates from there), not committed.
data=../shared/data
seed_from_data() {  # harness prefix-byte files...
  local harness=$1 prefix=$2
  shift 2
  for f in "$@"; do
    [ -f "$f" ] || continue
    { [ -n "$prefix" ] && printf "$prefix"; head -c 4096 "$f"; } > "build-fuzz/corpus/$harness/data_$(basename "$f")"
  done
}
for h in "${harnesses[@]}"; do
  mkdir -p "build-fuzz/corpus/$h" build-fuzz/findings
  cp tests/fuzz/corpus/"$h"/* "build-fuzz/corpus/$h/"
done
mkdir -p build-fuzz/corpus/{ply,pcd,depth,mesh,xyz}
seed_from_data ply "" "$data"/uwa/*.ply "$data"/sick_industrial/*.ply "$data"/icbin_mixed/cup_model.ply
seed_from_data pcd "" "$data"/pcl_milk/milk.pcd "$data"/pcl_milk/milk_tutorial_model.pcd "$data"/pcl_milk/bun0.pcd
seed_from_data depth '\x00' "$data"/icbin_mixed/camera.json "$data"/ipd_parts/camera_photoneo.json
seed_from_data mesh '\x01' "$data"/models_common3d/fandisk.obj

run() {
  local h=$1
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0 UBSAN_OPTIONS=print_stacktrace=1 \
    LSAN_OPTIONS=suppressions=tests/fuzz/lsan.supp \
    build-fuzz/fuzz_"$h" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
    -dict=tests/fuzz/binpose.dict -artifact_prefix=build-fuzz/findings/"$h"- -print_final_stats=1 \
    "build-fuzz/corpus/$h" > "build-fuzz/fuzz_$h.log" 2>&1
}
status=0
pids=()
for h in "${harnesses[@]}"; do
  run "$h" &
  pids+=($!)
  if [ ${#pids[@]} -ge "${FUZZ_JOBS:-2}" ]; then wait "${pids[0]}" || status=1; pids=("${pids[@]:1}"); fi
done
for p in "${pids[@]}"; do wait "$p" || status=1; done
for h in "${harnesses[@]}"; do
  echo "== fuzz_$h: $(grep -E '^stat::number_of_executed_units' "build-fuzz/fuzz_$h.log" | awk '{print $2}') runs," \
       "$(grep -Eo 'cov: [0-9]+' "build-fuzz/fuzz_$h.log" | tail -1), corpus $(ls "build-fuzz/corpus/$h" | wc -l) files"
  grep -E "ERROR|SUMMARY|contract broken|Test unit written" "build-fuzz/fuzz_$h.log" || true
done
[ $status -eq 0 ] || { echo "fuzz: a harness failed; the inputs are in build-fuzz/findings/"; exit 1; }
echo "fuzz: no finding in ${seconds} s per harness"
