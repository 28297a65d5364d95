#!/usr/bin/env bash
# The demo: installs dependencies, builds, and trains feature databases for the built-in cap
# and, when ../shared/data is present, for two real parts. Databases go to out/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
scripts/build.sh build > /dev/null
mkdir -p out
echo "== Built-in bottle cap (thesis-like 60 mm part)"
build/binpose train --model builtin:cap --out out/cap.bpdb
data=../shared/data
if [ -d "$data" ]; then
  echo; echo "== UWA parasaurolophus (real scan-based mesh, non-unit normals)"
  build/binpose train --model "$data/uwa/parasaurolophus_6700.ply" --out out/parasaurolophus.bpdb
  echo; echo "== IPD industrial part obj_000008"
  build/binpose train --model "$data/ipd_parts/models/obj_000008.ply" --out out/ipd_obj8.bpdb
fi
