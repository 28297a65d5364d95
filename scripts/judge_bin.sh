# Sourced by scripts/why_missed.sh and scripts/sparse_bins.sh: one simulated bin judged.
#   part_model PART        sets model, info (eval's --models-info, as an array) and id for cap or ipdN
#   judge_bin BIN OUT DB   detect (default preset), eval and check of every true pose: OUT.{det,eval,check}.json
# BINPOSE=path runs another build's detect and check.
models=../shared/data/ipd_parts/models

part_model() {
  case $1 in
    cap) model=builtin:cap; info=(); id=1 ;;
    ipd*) model=$(printf '%s/obj_%06d.ply' "$models" "${1#ipd}"); info=(--models-info "$models/models_info.json"); id=${1#ipd} ;;
    *) echo "unknown part $1" >&2; exit 2 ;;
  esac
}

judge_bin() {
  local bin=$1 out=$2 db=$3 binpose=${BINPOSE:-build/binpose}
  local scan=(--scene "$bin/depth.png" --intrinsics "$bin/camera.json")
  "$binpose" detect --model "$db" "${scan[@]}" --out "$out.det.json" > /dev/null
  build/binpose eval --truth "$bin" --result "$out.det.json" --model "$model" "${info[@]}" --obj-id "$id" --out "$out.eval.json" > /dev/null
  "$binpose" check --model "$db" "${scan[@]}" --poses "$bin/ground_truth.json" --out "$out.check.json" > /dev/null
}
