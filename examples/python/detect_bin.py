#!/usr/bin/env python3
"""Find every cap in a bin from Python: simulate a bin (or load a depth image), detect, print the
poses and draw them.

    examples/python/detect_bin.py                       # simulates a bin with `binpose simulate`
    examples/python/detect_bin.py --depth D.png --camera camera.json --model part.ply

Needs the module on the path (PYTHONPATH=build/python, or installed) and, to simulate, the
binpose CLI (--cli, default: `binpose` on PATH).
"""
import argparse
import json
import pathlib
import subprocess
import tempfile

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from PIL import Image

import binpose


def back_project(depth, camera):
    """The depth image's points in the camera frame, mm."""
    rows, cols = np.nonzero(depth)
    z = depth[rows, cols] * camera.get("depth_scale", 1.0)
    return np.stack([(cols - camera["cx"]) * z / camera["fx"], (rows - camera["cy"]) * z / camera["fy"], z], axis=1)


def draw(path, scan, result, model_points):
    """Top view: the scan grey by depth, each detection's posed model points in colour, ranked."""
    fig, ax = plt.subplots(figsize=(7, 7))
    step = max(1, len(scan) // 40000)
    ax.scatter(scan[::step, 0], scan[::step, 1], c=-scan[::step, 2], cmap="gray", s=1, linewidths=0)
    for rank, d in enumerate(result, 1):
        posed = model_points @ d.pose[:3, :3].T + d.pose[:3, 3]
        ax.scatter(posed[:, 0], posed[:, 1], s=2, linewidths=0)
        ax.annotate(str(rank), d.pose[:2, 3], color="red", fontsize=12, ha="center")
    ax.set_aspect("equal")
    ax.invert_yaxis()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"{len(result)} detections in {result.timing_ms['total']:.0f} ms")
    fig.savefig(path, dpi=100)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--depth", help="16-bit depth PNG (default: simulate a bin)")
    parser.add_argument("--camera", help="camera.json of the depth image (fx, fy, cx, cy, depth_scale)")
    parser.add_argument("--model", default="builtin:cap", help="part: mesh file or builtin:NAME")
    parser.add_argument("--cli", default="binpose", help="binpose CLI, to simulate a bin")
    parser.add_argument("--out", default="detections.png", help="drawing of the detections")
    args = parser.parse_args()

    truth = []
    with tempfile.TemporaryDirectory() as folder:
        if args.depth is None:
            subprocess.run([args.cli, "simulate", "--model", args.model, "--instances", "8", "--seed", "2",
                            "--out", folder], check=True, stdout=subprocess.DEVNULL)
            args.depth, args.camera = f"{folder}/depth.png", f"{folder}/camera.json"
            truth = json.loads(pathlib.Path(folder, "ground_truth.json").read_text())["instances"]
        camera = json.loads(pathlib.Path(args.camera).read_text())
        depth = np.array(Image.open(args.depth)).astype(np.uint16)  # PIL reads 16-bit grey as int32

    db = binpose.train(args.model, points=4000)
    result = binpose.Detector(db).detect_depth(depth, camera["fx"], camera["fy"], camera["cx"], camera["cy"],
                                               camera.get("depth_scale", 1.0))
    print(f"{len(result)} detections in {result.timing_ms['total']:.1f} ms (model {db.diameter:.1f} mm across)")
    for rank, d in enumerate(result, 1):
        t = d.pose[:3, 3]
        line = f"{rank:2d}  score {d.score:.3f}  t = ({t[0]:7.2f}, {t[1]:7.2f}, {t[2]:7.2f}) mm"
        if truth:
            error = min(np.linalg.norm(np.array(g["pose"])[:3, 3] - t) for g in truth)
            line += f"  {error:.2f} mm from the nearest true pose"
        print(line)
    model_points = np.array(binpose.train(args.model, points=500).model_points)
    draw(args.out, back_project(depth, camera), result, model_points)
    print(f"drawing: {args.out}")


if __name__ == "__main__":
    main()
