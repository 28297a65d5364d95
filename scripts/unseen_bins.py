#!/usr/bin/env python3
"""Sums scripts/unseen_bins.sh's evaluations per view: copies found (ADD-S under 0.1 diameter),
of them right by MSSD (under 10 mm: not turned over), detections off every copy, and recall over
the copies more than half visible.

  scripts/unseen_bins.py out/unseen/TAG [--parts]      (--parts: each part apart)
"""
import collections
import glob
import json
import os
import sys


def main():
    totals = collections.defaultdict(lambda: {"bins": 0, "found": 0, "mssd": 0, "det": 0, "half": 0, "half_found": 0})
    for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.json"))):
        if path.endswith(".det.json"):
            continue
        name = os.path.basename(path)[: -len(".json")]
        view = name.rsplit("-", 1 if "--parts" in sys.argv else 2)[0]  # without the seed (and the part)
        with open(path) as f:
            e = json.load(f)
        t = totals[view]
        t["bins"] += 1
        t["found"] += e["matched"]
        t["det"] += e["detections"]
        for i in e["instances"]:
            t["mssd"] += i["detection"] >= 0 and i["mssd_mm"] < 10
            if i["visib_fract"] > 0.5:
                t["half"] += 1
                t["half_found"] += i["detection"] >= 0
    print(f"{'view':<34} {'bins':>4} {'found':>5} {'mssd':>5} {'det':>4} {'off':>4} {'recall>half':>11}")
    totals["all"] = {k: sum(t[k] for t in list(totals.values())) for k in ("bins", "found", "mssd", "det", "half", "half_found")}
    for view, t in sorted(totals.items()):
        print(f"{view:<34} {t['bins']:>4} {t['found']:>5} {t['mssd']:>5} {t['det']:>4} {t['det'] - t['found']:>4} "
              f"{t['half_found'] / max(1, t['half']):>11.2f}")


if __name__ == "__main__":
    main()
