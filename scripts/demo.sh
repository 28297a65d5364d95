#!/usr/bin/env bash
# The demo: installs dependencies, builds, then on the built-in bottle cap runs
#   simulate (16 caps dropped into a bin, seen by a depth sensor) -> train -> detect -> eval
# and prints the summary and the path of the rendered picture (everything in out/demo/), then
# installs binpose (CLI, C++ package, Python module) under /usr/local: python3 -c "import binpose".
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
scripts/build.sh build > /dev/null
out=out/demo
mkdir -p "$out"
echo "== simulate: 16 built-in caps in a bin"
build/binpose simulate --model builtin:cap --instances 16 --seed 7 --out "$out/bin"
echo; echo "== train"
build/binpose train --model builtin:cap --out "$out/cap.bpdb"
echo; echo "== detect"
build/binpose detect --model "$out/cap.bpdb" --scene "$out/bin/depth.png" --intrinsics "$out/bin/camera.json" \
  --out "$out/result.json" --render "$out/detections.png" --export-ply "$out/detections.ply"
echo; echo "== eval against the exact ground truth"
build/binpose eval --truth "$out/bin" --result "$out/result.json" --model builtin:cap --out "$out/eval.json"
echo; echo "picture of the detections: $out/detections.png"
echo; echo "== install: the CLI, binpose::core (find_package(binpose)) and the Python module under /usr/local"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO cmake --install build > /dev/null
/usr/bin/python3 -c "import binpose; print('python3: binpose', binpose.__version__, 'from', binpose.__file__)"
