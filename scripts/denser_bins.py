#!/usr/bin/env python3
"""A simulated bin seen by a sensor with more pixels than independent depth samples: its depth
image upsampled (bilinear, no mixing with missing pixels; or nearest: each pixel repeated, as a
depth image registered to a sharper camera is), by 2 or any --factor, the intrinsics scaled to
match; or smoothed at its own resolution (an edge-preserving Gaussian of --factor pixels over the
neighbours within 10 mm, as a driver's spatial filter). The ground truth is copied (the scene's
geometry is the same).

  scripts/denser_bins.py SRC_BIN DST_BIN [--mode bilinear|nearest|smooth] [--factor F]
"""
import argparse
import json
import os
import shutil

import numpy as np
from PIL import Image


def smoothed(depth, sigma, same_surface=10.0):
    """Each pixel the Gaussian-weighted mean (sigma in pixels) of the pixels around it within
    `same_surface` mm of its depth (mm; 0: none, kept none)."""
    r, (h, w) = int(np.ceil(2 * sigma)), depth.shape
    num, den = np.zeros_like(depth, dtype=np.float64), np.zeros_like(depth, dtype=np.float64)
    pad = np.pad(depth, r)
    for dv in range(-r, r + 1):
        for du in range(-r, r + 1):
            weight = np.exp(-(du * du + dv * dv) / (2 * sigma * sigma))
            n = pad[r + dv:r + dv + h, r + du:r + du + w]
            ok = (n > 0) & (depth > 0) & (np.abs(n - depth) < same_surface)
            num += np.where(ok, weight * n, 0)
            den += np.where(ok, weight, 0)
    return np.where(depth > 0, num / np.maximum(den, 1e-9), 0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--mode", choices=("bilinear", "nearest", "smooth"), default="bilinear")
    ap.add_argument("--factor", type=float, default=2.0)
    a = ap.parse_args()
    os.makedirs(a.dst, exist_ok=True)
    for f in os.listdir(a.src):
        if f not in ("depth.png", "camera.json", "scene.ply") and os.path.isfile(os.path.join(a.src, f)):
            shutil.copy(os.path.join(a.src, f), a.dst)
    depth = np.array(Image.open(os.path.join(a.src, "depth.png"))).astype(np.float32)
    with open(os.path.join(a.src, "camera.json")) as f:
        cam = json.load(f)
    if a.mode == "smooth":
        shutil.copy(os.path.join(a.src, "camera.json"), a.dst)
        out = smoothed(depth * cam.get("depth_scale", 1.0), a.factor) / cam.get("depth_scale", 1.0)
        Image.fromarray(np.round(out).astype(np.uint16)).save(os.path.join(a.dst, "depth.png"))
        return
    h, w = depth.shape
    size = (round(a.factor * w), round(a.factor * h))
    if a.mode == "nearest":
        up = np.array(Image.fromarray(depth).resize(size, Image.NEAREST))
    else:
        up = np.array(Image.fromarray(depth).resize(size, Image.BILINEAR))
        known = np.array(Image.fromarray((depth > 0).astype(np.float32)).resize(size, Image.BILINEAR))
        up = np.where(known > 0.999, up, 0)  # a pixel next to a missing one stays missing
    Image.fromarray(np.round(up).astype(np.uint16)).save(os.path.join(a.dst, "depth.png"))
    sx, sy = size[0] / w, size[1] / h  # pixel centres: (c + 0.5) scales as the image's edges do
    cam.update(fx=sx * cam["fx"], fy=sy * cam["fy"], cx=sx * (cam["cx"] + 0.5) - 0.5, cy=sy * (cam["cy"] + 0.5) - 0.5,
               width=size[0], height=size[1])
    with open(os.path.join(a.dst, "camera.json"), "w") as f:
        json.dump(cam, f, indent=1)


if __name__ == "__main__":
    main()
