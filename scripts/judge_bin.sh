# Sourced by the scripts that simulate bins and judge what binpose finds in them.
#   part_model PART        sets model, info (eval's --models-info, as an array) and id for cap or ipdN
#   part_db DIR            sets db to DIR/PART.bpdb for part_model's part, trained there once (default 4000 points)
#   find_in_bin BIN OUT DB detect (default preset) and eval: OUT.{det,eval}.json
#   judge_bin BIN OUT DB   find_in_bin, and check of every true pose: OUT.check.json too
# BINPOSE=path runs another build's detect and check.
models=../shared/data/ipd_parts/models

part_model() {
  part=$1
  case $1 in
    cap) model=builtin:cap; info=(); id=1 ;;
    ipd*) model=$(printf '%s/obj_%06d.ply' "$models" "${1#ipd}"); info=(--models-info "$models/models_info.json"); id=${1#ipd} ;;
    *) echo "unknown part $1" >&2; exit 2 ;;
  esac
}

part_db() {
  mkdir -p "$1"
  db=$1/$part.bpdb
  [ -f "$db" ] || build/binpose train --model "$model" --out "$db" > /dev/null
}

find_in_bin() {
  local bin=$1 out=$2 db=$3
  "${BINPOSE:-build/binpose}" detect --model "$db" --scene "$bin/depth.png" --intrinsics "$bin/camera.json" --out "$out.det.json" > /dev/null
  build/binpose eval --truth "$bin" --result "$out.det.json" --model "$model" "${info[@]}" --obj-id "$id" --out "$out.eval.json" > /dev/null
}

judge_bin() {
  local bin=$1 out=$2 db=$3
  find_in_bin "$bin" "$out" "$db"
  "${BINPOSE:-build/binpose}" check --model "$db" --scene "$bin/depth.png" --intrinsics "$bin/camera.json" \
    --poses "$bin/ground_truth.json" --out "$out.check.json" > /dev/null
}
