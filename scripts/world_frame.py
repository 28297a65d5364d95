#!/usr/bin/env python3
"""The bench's simulated bins as unorganized PLY files in a world frame, detected from the guessed
viewpoint, the origin and the true viewpoint, against the same file in the camera's frame.

The world frame is the bin's (z up, floor at z = 0) turned by 0.6 rad about z and moved by
(400, -250, 750) mm, as a robot's base frame beside the bin would be. Each detection's pose is
taken back into the camera frame and scored by `binpose eval` against the bin's ground truth.

    scripts/world_frame.py [--cache out/bench] [--data ../shared/data] [--binpose build/binpose]

Needs numpy. Prints one row per bin and the sums; writes nothing outside a temporary folder.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

BINS = ["cap-16", "cap-32", "ipd0-16", "ipd0-32", "ipd8-16", "ipd8-32", "cap-16-sl", "ipd0-16-sl", "ipd8-16-sl",
        "ipd1-16-sl", "cap-16-ind", "ipd0-16-ind", "ipd8-16-ind", "ipd1-16-ind"]


def read_ply_points(path):
    with open(path, "rb") as f:
        count, fmt = 0, ""
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"{path}: no end_header")
            if line.startswith(b"element vertex"):
                count = int(line.split()[2])
            if line.startswith(b"format"):
                fmt = line.split()[1].decode()
            if line.startswith(b"end_header"):
                break
        if fmt == "ascii":
            return np.loadtxt(f, max_rows=count, ndmin=2)[:, :3]
        return np.frombuffer(f.read(count * 12), dtype="<f4").reshape(-1, 3).astype(float)


def write_ply(path, points):
    with open(path, "wb") as f:
        f.write(b"ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % len(points))
        f.write(b"property float x\nproperty float y\nproperty float z\nend_header\n")
        f.write(points.astype("<f4").tobytes())


def world_from_bin():
    c, s = np.cos(0.6), np.sin(0.6)
    w = np.eye(4)
    w[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    w[:3, 3] = [400, -250, 750]
    return w


def model_of(name, data, cache):
    if name.startswith("cap"):
        return "builtin:cap", ["--models-info", f"{cache}/{name}/models_info.json", "--obj-id", "1"]
    obj = name.split("ipd")[1].split("-")[0]
    return (f"{data}/ipd_parts/models/obj_{int(obj):06d}.ply",
            ["--models-info", f"{data}/ipd_parts/models/models_info.json", "--obj-id", obj])


def run_bin(name, a, work, databases):
    model, info = model_of(name, a.data, a.cache)
    if model not in databases:
        databases[model] = os.path.join(work, f"db{len(databases)}.bpdb")
        subprocess.run([a.binpose, "train", "--model", model, "--out", databases[model]], check=True, capture_output=True)
    truth = json.load(open(f"{a.cache}/{name}/ground_truth.json"))
    world_from_camera = world_from_bin() @ np.linalg.inv(np.array(truth["camera_from_world"]))
    camera = read_ply_points(f"{a.cache}/{name}/scene.ply")
    write_ply(f"{work}/camera.ply", camera)
    write_ply(f"{work}/world.ply", camera @ world_from_camera[:3, :3].T + world_from_camera[:3, 3])
    sensor = ["--viewpoint"] + [f"{x:.3f}" for x in world_from_camera[:3, 3]]
    runs = [("camera", "camera.ply", [], np.eye(4)), ("guessed", "world.ply", [], world_from_camera),
            ("origin", "world.ply", ["--viewpoint", "0", "0", "0"], world_from_camera),
            ("true", "world.ply", sensor, world_from_camera)]
    row = {}
    for tag, scene, extra, frame in runs:
        out = f"{work}/{tag}.json"
        subprocess.run([a.binpose, "detect", "--model", databases[model], "--scene", f"{work}/{scene}", "--out", out] + extra,
                       check=True, capture_output=True)
        result = json.load(open(out))
        back = np.linalg.inv(frame)
        for d in result["detections"]:
            d["pose"] = (back @ np.array(d["pose"])).tolist()
        json.dump(result, open(out, "w"))
        subprocess.run([a.binpose, "eval", "--truth", f"{a.cache}/{name}", "--result", out, "--model", model, "--out",
                        f"{work}/{tag}.eval.json"] + info, check=True, capture_output=True)
        e = json.load(open(f"{work}/{tag}.eval.json"))
        found = sum(1 for i in e["instances"] if i["detection"] >= 0)
        row[tag] = (found, len(result["detections"]), len(e["instances"]))
    return row


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--cache", default="out/bench", help="the bench's simulated bins (bench_e2e --cache)")
    p.add_argument("--data", default="../shared/data")
    p.add_argument("--binpose", default="build/binpose")
    a = p.parse_args()
    tags = ["camera", "guessed", "origin", "true"]
    sums = {t: [0, 0, 0] for t in tags}
    print("bin          " + "  ".join(f"{t:>16}" for t in tags) + "   (found / detections / copies)")
    with tempfile.TemporaryDirectory() as work:
        databases = {}
        for name in BINS:
            if not os.path.exists(f"{a.cache}/{name}/scene.ply"):
                sys.exit(f"{a.cache}/{name}/scene.ply missing: run build/bench/binpose_bench_e2e --cache {a.cache} first")
            row = run_bin(name, a, work, databases)
            print(f"{name:12} " + "  ".join(f"{'%d / %d / %d' % row[t]:>16}" for t in tags), flush=True)
            for t in tags:
                sums[t] = [s + v for s, v in zip(sums[t], row[t])]
    print(f"{'sum':12} " + "  ".join(f"{'%d / %d / %d' % tuple(sums[t]):>16}" for t in tags))
    for t in tags:
        found, detections, copies = sums[t]
        print(f"{t:8} recall {found / copies:.0%}  precision {found / max(detections, 1):.0%}")


if __name__ == "__main__":
    main()
