#!/usr/bin/env bash
# The same answer whatever the thread count: every bin of the fresh cache (scripts/fresh_bins.sh
# simulates it) detected with 1, 2 and 3 worker threads (default preset); prints each bin whose
# detections (poses and scores, as written) differ, and the count.
#   scripts/threads_check.sh            (needs a build and out/fresh/cache; about a minute)
# BINPOSE=path checks another build.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/judge_bin.sh
bins=(out/fresh/cache/*/)
[ -d "${bins[0]}" ] || { echo "no bins in out/fresh/cache: run scripts/fresh_bins.sh first" >&2; exit 2; }
mkdir -p out/threads/run
differ=0
for bin in "${bins[@]}"; do
  bin=${bin%/}
  name=$(basename "$bin")
  part=${name%%-*}
  part_model "$part"
  part_db out/threads/db
  for threads in 1 2 3; do
    "${BINPOSE:-build/binpose}" detect --threads "$threads" --model "$db" --scene "$bin/depth.png" \
      --intrinsics "$bin/camera.json" --out "out/threads/run/$threads.json" > /dev/null
  done
  if ! python3 - <<'PY'
import json, sys
runs = [[(d["pose"], d["score"]) for d in json.load(open(f"out/threads/run/{t}.json"))["detections"]] for t in (1, 2, 3)]
sys.exit(0 if runs[0] == runs[1] == runs[2] else 1)
PY
  then
    echo "differs: $name"
    differ=$((differ + 1))
  fi
done
echo "${#bins[@]} bins, $differ differ across 1, 2 and 3 threads"
[ "$differ" -eq 0 ]
