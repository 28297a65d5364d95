#!/usr/bin/env python3
"""A simulated bin seen by a sensor with more pixels than independent depth samples: its depth
image upsampled (bilinear, no mixing with missing pixels; or nearest: each pixel repeated, as a
depth image registered to a sharper camera is), by 2 or any --factor, the intrinsics scaled to
match, the ground truth copied (the scene's geometry is the same).

  scripts/denser_bins.py SRC_BIN DST_BIN [--mode bilinear|nearest] [--factor F]
"""
import argparse
import json
import os
import shutil

import numpy as np
from PIL import Image


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--mode", choices=("bilinear", "nearest"), default="bilinear")
    ap.add_argument("--factor", type=float, default=2.0)
    a = ap.parse_args()
    os.makedirs(a.dst, exist_ok=True)
    for f in os.listdir(a.src):
        if f not in ("depth.png", "camera.json", "scene.ply") and os.path.isfile(os.path.join(a.src, f)):
            shutil.copy(os.path.join(a.src, f), a.dst)
    depth = np.array(Image.open(os.path.join(a.src, "depth.png"))).astype(np.float32)
    h, w = depth.shape
    size = (round(a.factor * w), round(a.factor * h))
    if a.mode == "nearest":
        up = np.array(Image.fromarray(depth).resize(size, Image.NEAREST))
    else:
        up = np.array(Image.fromarray(depth).resize(size, Image.BILINEAR))
        known = np.array(Image.fromarray((depth > 0).astype(np.float32)).resize(size, Image.BILINEAR))
        up = np.where(known > 0.999, up, 0)  # a pixel next to a missing one stays missing
    Image.fromarray(np.round(up).astype(np.uint16)).save(os.path.join(a.dst, "depth.png"))
    with open(os.path.join(a.src, "camera.json")) as f:
        cam = json.load(f)
    sx, sy = size[0] / w, size[1] / h  # pixel centres: (c + 0.5) scales as the image's edges do
    cam.update(fx=sx * cam["fx"], fy=sy * cam["fy"], cx=sx * (cam["cx"] + 0.5) - 0.5, cy=sy * (cam["cy"] + 0.5) - 0.5,
               width=size[0], height=size[1])
    with open(os.path.join(a.dst, "camera.json"), "w") as f:
        json.dump(cam, f, indent=1)


if __name__ == "__main__":
    main()
