#!/usr/bin/env bash
# Denser scans with correlated noise: twelve of the fresh structured-light bins (cap, IPD obj 0
# and 8; scripts/fresh_bins.sh's seed offsets 1000-4000) and the same bins upsampled 2x
# (scripts/denser_bins.py: twice the pixels, the noise correlated over two), each found with
# `binpose detect` (default preset) and scored with `binpose eval`, summed per part and view
# (scripts/unseen_bins.py). The scene is the same: what changes is what the scan's own noise
# estimate reads on it.
#   scripts/denser_bins.sh TAG [bilinear|nearest|smooth [FACTOR]]   (needs a build and scripts/fresh_bins.sh's cache)
# nearest repeats each pixel (over 2 x 2 by default), as a depth image registered to a camera with
# FACTOR times the pixels each way does; smooth keeps the resolution and smooths by FACTOR pixels.
# BINPOSE=path runs another build's detector on the same bins.
set -euo pipefail
cd "$(dirname "$0")/.."
tag=${1:?usage: scripts/denser_bins.sh TAG [bilinear|nearest|smooth [FACTOR]]}
mode=${2:-bilinear}
factor=${3:-2}
cache=out/denser/cache; [ "$mode" = bilinear ] || cache=out/denser/cache-$mode-$factor
models=../shared/data/ipd_parts/models
mkdir -p "$cache" out/denser/db "out/denser/$tag"
py=python3; [ -x /usr/bin/python3 ] && py=/usr/bin/python3  # Debian's, with numpy and PIL
for part in cap ipd0 ipd8; do
  case $part in
    cap) model=builtin:cap; info=(); id=1; seed=01;;
    ipd0) model=$models/obj_000000.ply; info=(--models-info "$models/models_info.json"); id=0; seed=03;;
    ipd8) model=$models/obj_000008.ply; info=(--models-info "$models/models_info.json"); id=8; seed=05;;
  esac
  db=out/denser/db/$part.bpdb
  [ -f "$db" ] || build/binpose train --model "$model" --out "$db" > /dev/null
  for k in 1 2 3 4; do
    src=out/fresh/cache/$part-16-sl-seed${k}1$seed
    [ -f "$src/depth.png" ] || { echo "missing $src: run scripts/fresh_bins.sh first" >&2; exit 1; }
    dense=$cache/$part-16-sl-seed${k}1$seed
    [ -f "$dense/depth.png" ] || "$py" scripts/denser_bins.py "$src" "$dense" --mode "$mode" --factor "$factor"
    for view in native:$src dense:$dense; do
      bin=${view#*:}; out=out/denser/$tag/${view%%:*}-$part-$k
      "${BINPOSE:-build/binpose}" detect --model "$db" --scene "$bin/depth.png" --intrinsics "$bin/camera.json" --out "$out.det.json" > "$out.log" 2>&1
      build/binpose eval --truth "$bin" --result "$out.det.json" --model "$model" "${info[@]}" --obj-id "$id" --out "$out.json" > /dev/null
    done
  done
done
python3 scripts/unseen_bins.py "out/denser/$tag" --parts
for view in native dense; do
  printf '%s: noise mm' "$view"
  for f in out/denser/"$tag"/"$view"-*.det.json; do python3 -c "import json,sys; print(' %.2f' % json.load(open(sys.argv[1]))['noise_mm'], end='')" "$f"; done
  echo
done
