#!/usr/bin/env bash
# Nearly empty bins: six copies in the bin, as a robot leaves it near the end of its picking,
# most of them lying apart on the floor. The cap and IPD obj 0, 1 and 8, each seen by the ideal,
# industrial, structured-light and time-of-flight sensor models (the bench's distances), seeds
# 501-506. Simulated once into out/sparse/cache with `binpose simulate`, found with `binpose
# detect` (default preset), scored with `binpose eval`, and each copy's true pose judged with
# `binpose check`: scripts/why_missed.py sums them, each part apart.
#   scripts/sparse_bins.sh TAG        (needs a build; results in out/sparse/TAG)
# BINPOSE=path runs another build's binpose on the same bins.
set -euo pipefail
cd "$(dirname "$0")/.."
tag=${1:?usage: scripts/sparse_bins.sh TAG}
source scripts/judge_bin.sh
mkdir -p out/sparse/cache "out/sparse/$tag"
# sensor, its short name in the bins' names (as the bench's), distance mm
sensors=("ideal clean 500" "industrial ind 1000" "structured-light sl 800" "tof tof 800")
for part in cap ipd0 ipd1 ipd8; do
  part_model "$part"
  part_db out/sparse/db
  for entry in "${sensors[@]}"; do
    read -r sensor short distance <<< "$entry"
    for seed in 501 502 503 504 505 506; do
      name=$part-6-$short-seed$seed
      bin=out/sparse/cache/$name
      [ -f "$bin/depth.png" ] || build/binpose simulate --model "$model" ${info[@]/--models-info/--model-info} --obj-id "$id" \
        --instances 6 --sensor "$sensor" --distance "$distance" --seed "$seed" --out "$bin" > /dev/null
      judge_bin "$bin" "out/sparse/$tag/$name" "$db"
    done
  done
done
python3 scripts/why_missed.py "out/sparse/$tag" --parts
