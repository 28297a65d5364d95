#!/usr/bin/env python3
"""Sums scripts/depth_offsets.sh's results per sensor and depth offset: the copies more than half
visible and how many of them are found, the detections and how many are off every copy, and the
precision.

  scripts/depth_offsets.py out/offsets/TAG
"""
import collections
import glob
import json
import os
import sys


def main():
    totals = collections.defaultdict(collections.Counter)
    for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.eval.json"))):
        name = os.path.basename(path)[: -len(".eval.json")]
        sensor = "industrial" if "-ind-" in name else "clean"
        offset = name.rsplit("-z", 1)[1]
        with open(path) as f:
            evaluation = json.load(f)
        t = totals[(sensor, offset)]
        t["detections"] += evaluation["detections"]
        t["off"] += evaluation["detections"] - evaluation["matched"]
        for instance in evaluation["instances"]:
            if instance["visib_fract"] > 0.5:
                t["copies"] += 1
                t["found"] += instance["detection"] >= 0
    print(f"{'sensor':<11} {'offset mm':>9} {'copies > half':>13} {'found':>6} {'detections':>10} {'off':>4} {'precision':>9}")
    for (sensor, offset), t in sorted(totals.items()):
        precision = 1 - t["off"] / t["detections"] if t["detections"] else 0
        print(f"{sensor:<11} {offset:>9} {t['copies']:>13} {t['found']:>6} {t['detections']:>10} {t['off']:>4} {precision:>9.3f}")


if __name__ == "__main__":
    main()
