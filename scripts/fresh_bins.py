#!/usr/bin/env python3
"""Sums bench_e2e result files (binpose rows) per sensor and per part: copies found, detections,
detections off every copy (not correct by the bench's ADD-S rule), mean recall over the copies
more than half visible, mean detection time.

  scripts/fresh_bins.py out/fresh/TAG-*.json
"""
import collections
import json
import sys


def kind(name):
    parts = name.split("-")
    return parts[2] if len(parts) == 3 else "clean", parts[0]


def main():
    totals = collections.defaultdict(lambda: {"bins": 0, "found": 0, "detections": 0, "right": 0, "half": 0.0, "ms": 0.0})
    for path in sys.argv[1:]:
        with open(path) as f:
            for r in json.load(f)["rows"]:
                if r["method"] != "binpose":
                    continue
                sensor, part = kind(r["input"])
                for key in (sensor, f"{sensor} {part}"):
                    t = totals[key]
                    t["bins"] += 1
                    t["found"] += r["found"]
                    t["detections"] += r["detections"]
                    t["right"] += round(r["precision"] * r["detections"])
                    t["half"] += r["recall_over_half_visible"]
                    t["ms"] += r["detect_ms_median"]
    print(f"{'bins':<14} {'n':>3} {'found':>6} {'det':>5} {'off':>4} {'prec':>5} {'recall>half':>11} {'ms':>5}")
    for key in sorted(totals):
        t = totals[key]
        n = t["bins"]
        print(f"{key:<14} {n:>3} {t['found']:>6} {t['detections']:>5} {t['detections'] - t['right']:>4} "
              f"{t['right'] / max(1, t['detections']):>5.2f} {t['half'] / n:>11.2f} {t['ms'] / n:>5.0f}")


if __name__ == "__main__":
    main()
