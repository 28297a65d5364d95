#!/usr/bin/env python3
"""Draws `binpose detect`'s best detections on the SICK scan's box: the scan from above (grey by
height) and from the side, each detection's posed CAD vertices in its colour.

    build/binpose detect --model sick.bpdb --scene ../shared/data/sick_industrial/data.ply --out sick.json
    scripts/sick_overlay.py --result sick.json --out docs/sick_overlay.png

Needs numpy and matplotlib (and PIL for a smaller file).
"""
import argparse
import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# The vendor's crop box (main.lua), widened by 20 mm: the box the device lies in.
CENTRE, HALF = np.array([0.0, 120.0, 400.0]), np.array([150.0, 200.0, 120.0])
COLOURS = ["red", "lime", "deepskyblue", "orange", "magenta"]


def read_ply(path):
    with open(path, "rb") as f:
        count, binary = 0, False
        while True:
            line = f.readline()
            if line.startswith(b"element vertex"):
                count = int(line.split()[2])
            binary |= line.startswith(b"format binary")
            if line.startswith(b"end_header"):
                break
        if binary:
            return np.frombuffer(f.read(count * 12), dtype="<f4").reshape(-1, 3).astype(float)
        return np.loadtxt(f, max_rows=count, ndmin=2)[:, :3]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", default="../shared/data/sick_industrial")
    p.add_argument("--result", required=True, help="binpose detect --out JSON")
    p.add_argument("--out", required=True, help="PNG to write")
    p.add_argument("--count", type=int, default=2, help="detections drawn, best first")
    a = p.parse_args()
    scan = read_ply(f"{a.data}/data.ply")
    box = scan[np.all(np.abs(scan - CENTRE) < HALF, axis=1)]
    model = read_ply(f"{a.data}/V2D63xModel.ply")[::10]
    detections = json.load(open(a.result))["detections"][: a.count]
    fig, (top, side) = plt.subplots(1, 2, figsize=(12, 6.5))
    top.scatter(box[:, 0], box[:, 1], c=box[:, 2], s=3, cmap="gray", vmin=370, vmax=480)
    side.scatter(box[:, 0], box[:, 2], c="grey", s=2)
    for rank, d in enumerate(detections):
        pose = np.array(d["pose"])
        posed = model @ pose[:3, :3].T + pose[:3, 3]
        label = f"{rank + 1}: score {d['score']:.2f}"
        top.scatter(posed[:, 0], posed[:, 1], s=1, c=COLOURS[rank % len(COLOURS)], alpha=0.25, label=label)
        side.scatter(posed[:, 0], posed[:, 2], s=1, c=COLOURS[rank % len(COLOURS)], alpha=0.25)
    top.set(title="from above (x, y mm; grey: height)", aspect="equal")
    side.set(title="from the side (x, z mm)", aspect="equal")
    top.legend(loc="upper right", markerscale=8)
    fig.tight_layout()
    fig.savefig(a.out, dpi=60)
    try:  # a 64-colour palette: a quarter of the size, for docs/
        from PIL import Image
        Image.open(a.out).convert("RGB").quantize(colors=64).save(a.out, optimize=True)
    except ImportError:
        pass


if __name__ == "__main__":
    main()
