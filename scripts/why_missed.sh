#!/usr/bin/env bash
# Why copies are missed. Each simulated bin of out/fresh/cache (scripts/fresh_bins.sh makes them)
# is detected (binpose detect), scored against its ground truth (binpose eval), and the true pose
# of each of its copies judged as detect judges its own (binpose check). The copies more than
# half visible that detect misses are then counted by the verdict on their true pose
# (scripts/why_missed.py): it stands (the search never reached it), or the first test refusing it.
#   scripts/why_missed.sh TAG [GLOB]      (default GLOB '*-seed*'; needs a build; out/why/TAG)
# BINPOSE=path runs another build's binpose.
set -euo pipefail
cd "$(dirname "$0")/.."
tag=${1:?usage: scripts/why_missed.sh TAG [GLOB]}
glob=${2:-*-seed*}
source scripts/judge_bin.sh
mkdir -p "out/why/$tag"
bins=(out/fresh/cache/$glob)
[ -d "${bins[0]}" ] || { echo "no bins match out/fresh/cache/$glob: run scripts/fresh_bins.sh first" >&2; exit 2; }
for bin in "${bins[@]}"; do
  name=$(basename "$bin")
  part=${name%%-*}
  part_model "$part"
  part_db out/why/db
  judge_bin "$bin" "out/why/$tag/$name" "$db"
done
python3 scripts/why_missed.py "out/why/$tag"
