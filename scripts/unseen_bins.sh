#!/usr/bin/env bash
# Bins the bench never sees: its parts seen from other distances and with other resolutions, IPD
# parts it does not hold (obj 4, a block; obj 10) seen as the bench sees its bins, and three meshes
# of ../shared/data/models_common3d (fandisk, rocker arm, bunny; scaled to 79-99 mm across, 12 copies)
# seen by each sensor. Simulated
# with `binpose simulate`, found with `binpose detect` (default preset), scored with `binpose
# eval`, summed per view (scripts/unseen_bins.py). A rule set on the bench's bins is checked here
# on views and parts it was not set on.
#   scripts/unseen_bins.sh TAG        (needs a build; bins are simulated once into out/unseen/cache)
# BINPOSE=path runs another build's detector on the same bins (a before-and-after comparison).
set -euo pipefail
cd "$(dirname "$0")/.."
tag=${1:?usage: scripts/unseen_bins.sh TAG}
data=../shared/data
models=$data/ipd_parts/models
mkdir -p out/unseen/cache out/unseen/db "out/unseen/$tag"
# sensor:distance_mm[:width x height x fx], the parts each is tried with
views=("structured-light:600 cap ipd0 ipd8" "structured-light:1100 cap ipd0 ipd8" "industrial:600 cap ipd0 ipd8"
       "industrial:1500 cap ipd0 ipd8" "tof:1200 cap ipd0 ipd8" "ideal:900 cap ipd0 ipd8" "ideal:1500 cap ipd0 ipd8"
       "tof:1000:512x424x365 cap ipd0 ipd8" "ideal:500 ipd4 ipd10" "industrial:1000:1280x960x1100 ipd4 ipd10"
       "structured-light:800 ipd4 ipd10" "tof:800 ipd4 ipd10" "structured-light:800 fandisk rocker bunny"
       "industrial:1000 fandisk rocker bunny" "tof:900 fandisk rocker bunny" "ideal:600 fandisk rocker bunny")
# The common meshes are unitless (fandisk, rocker arm) or in metres (bunny): scaled copies in mm.
mkdir -p out/unseen/models
common=$data/models_common3d
declare -A scale=([fandisk]=12 [rocker]=80 [bunny]=500) mesh=([fandisk]=fandisk [rocker]=rocker-arm [bunny]=stanford-bunny)
for part in "${!scale[@]}"; do
  out=out/unseen/models/$part.obj
  [ -f "$out" ] || awk -v s="${scale[$part]}" '/^v /{printf "v %.6f %.6f %.6f\n", $2*s, $3*s, $4*s; next} {print}' \
    "$common/${mesh[$part]}.obj" > "$out"
done
model_of() { case $1 in cap) echo builtin:cap;; ipd*) printf '%s/obj_%06d.ply' "$models" "${1#ipd}";; *) echo "out/unseen/models/$1.obj";; esac; }
for view in "${views[@]}"; do
  read -r spec parts <<< "$view"
  IFS=: read -r sensor distance res <<< "$spec"
  size=(); name=$sensor-$distance
  if [ -n "${res:-}" ]; then IFS=x read -r w h f <<< "$res"; size=(--width "$w" --height "$h" --fx "$f"); name=$name-$w; fi
  for part in $parts; do
    model=$(model_of "$part"); info=(); id=1; copies=16
    case $part in ipd*) info=(--models-info "$models/models_info.json"); id=${part#ipd};; cap) ;; *) copies=12;; esac
    db=out/unseen/db/$part.bpdb
    [ -f "$db" ] || build/binpose train --model "$model" --out "$db" > /dev/null
    for seed in 21 22; do
      bin=out/unseen/cache/$name-$part-$seed
      [ -f "$bin/depth.png" ] || build/binpose simulate --model "$model" ${info[@]/--models-info/--model-info} --obj-id "$id" \
        --instances "$copies" --sensor "$sensor" --distance "$distance" "${size[@]}" --seed "$seed" --out "$bin" > /dev/null
      out=out/unseen/$tag/$name-$part-$seed
      "${BINPOSE:-build/binpose}" detect --model "$db" --scene "$bin/depth.png" --intrinsics "$bin/camera.json" --out "$out.det.json" > "$out.log" 2>&1
      build/binpose eval --truth "$bin" --result "$out.det.json" --model "$model" "${info[@]}" --obj-id "$id" --out "$out.json" > /dev/null
    done
  done
done
python3 scripts/unseen_bins.py "out/unseen/$tag"
