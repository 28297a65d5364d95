#!/usr/bin/env bash
# Fresh seeded bins: the bench's simulated inputs at other seeds (--seed-offset), binpose only,
# one run each, summed per sensor (scripts/fresh_bins.py). What a rule gains on the bench's own
# bins is checked here on bins it was not set on.
#   scripts/fresh_bins.sh TAG [OFFSET ...]      (default offsets 1000 to 8000; needs a build)
# Bins are simulated once into out/fresh/cache; results go to out/fresh/TAG-OFFSET.json.
set -euo pipefail
cd "$(dirname "$0")/.."
tag=${1:?usage: scripts/fresh_bins.sh TAG [OFFSET ...]}
shift
offsets=("$@")
[ ${#offsets[@]} -eq 0 ] && offsets=(1000 2000 3000 4000 5000 6000 7000 8000)
noisy=cap-16-sl,ipd0-16-sl,ipd8-16-sl,ipd1-16-sl,cap-16-tof,ipd0-16-tof,ipd8-16-tof,ipd1-16-tof
other=cap-16-ind,ipd0-16-ind,ipd8-16-ind,ipd1-16-ind,cap-16,ipd0-16
mkdir -p out/fresh
for off in "${offsets[@]}"; do
  inputs=$noisy
  [ "$off" -le 3000 ] && inputs=$noisy,$other  # industrial and clean bins: the first three offsets
  echo "fresh bins: seed offset $off" >&2
  build/bench/binpose_bench_e2e --data ../shared/data --cache out/fresh/cache --repeats 1 --methods binpose \
    --seed-offset "$off" --inputs "$inputs" --out "out/fresh/$tag-$off.json" > "out/fresh/$tag-$off.log" 2>&1
done
python3 scripts/fresh_bins.py out/fresh/"$tag"-*.json
