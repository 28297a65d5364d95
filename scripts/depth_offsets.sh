#!/usr/bin/env bash
# The same bins seen from 0, 1, 2 and 3 mm farther: quiet scans (the ideal sensor at 500 mm, the
# industrial one at 1 m, 1280 x 960, as the bench sees them) of 16 copies of the cap and IPD obj
# 0, 1 and 8, seeds 601-603. The parts lie as they fell (the simulation does not depend on the
# distance) and only the depth moves, so what changes with it is the scan's sampling: a flat
# floor or a layer of flat tops straddles the sub-sampling's voxel boundaries at some depths and
# not at others. Simulated once into out/offsets/cache with `binpose simulate`, found with `binpose
# detect` (default preset), scored with `binpose eval`, summed per offset by scripts/depth_offsets.py.
#   scripts/depth_offsets.sh TAG        (needs a build; results in out/offsets/TAG)
# BINPOSE=path runs another build's binpose on the same bins.
set -euo pipefail
cd "$(dirname "$0")/.."
tag=${1:?usage: scripts/depth_offsets.sh TAG}
source scripts/judge_bin.sh
mkdir -p out/offsets/cache "out/offsets/$tag"
# sensor, its short name in the bins' names (as the bench's), distance mm, image size and focal length
sensors=("ideal clean 500 640 480 550" "industrial ind 1000 1280 960 1100")
for part in cap ipd0 ipd1 ipd8; do
  part_model "$part"
  part_db out/offsets/db
  for entry in "${sensors[@]}"; do
    read -r sensor short distance width height fx <<< "$entry"
    for seed in 601 602 603; do
      for offset in 0 1 2 3; do
        name=$part-16-$short-seed$seed-z$offset
        bin=out/offsets/cache/$name
        [ -f "$bin/depth.png" ] || build/binpose simulate --model "$model" ${info[@]/--models-info/--model-info} --obj-id "$id" \
          --sensor "$sensor" --distance $((distance + offset)) --width "$width" --height "$height" --fx "$fx" --seed "$seed" \
          --out "$bin" > /dev/null
        find_in_bin "$bin" "out/offsets/$tag/$name" "$db"
      done
    done
  done
done
python3 scripts/depth_offsets.py "out/offsets/$tag"
