#!/usr/bin/env python3
"""Detect a part in a depth image with the default preset and draw each detection's posed model
over the matching colour image, ranked, with its score: how docs/ shows real scans that have no
ground truth.

    PYTHONPATH=build/python scripts/overlay.py --model ../shared/data/icbin_mixed/cup_model.ply \
        --depth ../shared/data/icbin_mixed/depth/0001.png --rgb ../shared/data/icbin_mixed/rgb/0001.png \
        --camera ../shared/data/icbin_mixed/camera.json --out docs/icbin_frame1.png

The colour image must be registered to the depth image (same intrinsics), as in BOP datasets.
"""
import argparse
import json

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from PIL import Image

import binpose

COLOURS = plt.get_cmap("tab10").colors


def project(points, pose, camera):
    """Pixel coordinates (u, v) of model points posed into the camera frame."""
    posed = points @ pose[:3, :3].T + pose[:3, 3]
    z = np.maximum(posed[:, 2], 1e-6)
    return camera["fx"] * posed[:, 0] / z + camera["cx"], camera["fy"] * posed[:, 1] / z + camera["cy"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True, help="the part: mesh file or builtin:NAME (mm)")
    parser.add_argument("--depth", required=True, help="16-bit depth PNG")
    parser.add_argument("--rgb", required=True, help="colour image registered to the depth image")
    parser.add_argument("--camera", required=True, help="camera.json (fx, fy, cx, cy, depth_scale)")
    parser.add_argument("--out", required=True, help="PNG to write")
    args = parser.parse_args()

    camera = json.load(open(args.camera))
    depth = np.array(Image.open(args.depth)).astype(np.uint16)
    db = binpose.train(args.model)
    result = binpose.Detector(db).detect_depth(depth, camera["fx"], camera["fy"], camera["cx"], camera["cy"],
                                               camera.get("depth_scale", 1.0))
    rgb = np.array(Image.open(args.rgb).convert("RGB"))
    height, width = rgb.shape[:2]
    fig = plt.figure(figsize=(width / 100, height / 100), dpi=100)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.imshow(rgb)
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.axis("off")
    model = np.asarray(db.model_points)
    for rank, d in enumerate(result, 1):
        u, v = project(model, d.pose, camera)
        colour = COLOURS[(rank - 1) % len(COLOURS)]
        ax.scatter(u, v, s=1, color=colour, alpha=0.35, linewidths=0)
        cu, cv = project(model.mean(axis=0, keepdims=True), d.pose, camera)
        ax.text(cu[0], cv[0], f"{rank}: {d.score:.2f}", color="white", fontsize=9, ha="center", va="center",
                bbox=dict(facecolor=colour, alpha=0.8, pad=1, linewidth=0))
    ax.text(5, 15, f"{len(result)} detections, {result.timing_ms['total']:.0f} ms", color="yellow", fontsize=10)
    fig.canvas.draw()
    drawn = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[:, :, :3])
    drawn.quantize(colors=255, method=Image.Quantize.FASTOCTREE).save(args.out, optimize=True)  # a palette: a fifth of the bytes
    print(f"{args.out}: {len(result)} detections")
    for rank, d in enumerate(result, 1):
        print(f"  {rank}: score {d.score:.3f} at {np.array2string(d.pose[:3, 3], precision=1)} mm")


if __name__ == "__main__":
    main()
