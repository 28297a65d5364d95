#!/usr/bin/env python3
"""Sums scripts/why_missed.sh's (or scripts/sparse_bins.sh's) results per sensor: the copies more
than half visible, those detect misses by the verdict of `binpose check` on their true pose
("stands": the search never reached it; else the first test refusing it, as a clique's pose),
and the detections off every copy.

  scripts/why_missed.py out/why/TAG [--parts] [--list]   (--parts: each part apart; --list: each missed copy)
"""
import collections
import glob
import json
import os
import sys

VERDICTS = ["stands", "score", "visible_support", "sunk", "behind_face", "outline"]


def sensor_of(name):
    for key, sensor in (("-sl-", "structured light"), ("-tof-", "time of flight"), ("-ind-", "industrial")):
        if key in name:
            return sensor
    return "clean"


def verdict_of(check):
    return "stands" if "none" in (check["as_found"], check["as_laid"]) else check["as_found"]


def main():
    missed = collections.defaultdict(collections.Counter)
    totals = collections.defaultdict(collections.Counter)
    for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.eval.json"))):
        name = os.path.basename(path)[: -len(".eval.json")]
        with open(path) as f:
            evaluation = json.load(f)
        with open(path.replace(".eval.json", ".check.json")) as f:
            checks = json.load(f)["checks"]
        key = sensor_of(name) + (" " + name.split("-")[0] if "--parts" in sys.argv else "")
        totals[key]["off"] += evaluation["detections"] - evaluation["matched"]
        for instance in evaluation["instances"]:
            if instance["visib_fract"] <= 0.5:
                continue
            totals[key]["copies"] += 1
            if instance["detection"] >= 0:
                continue
            check = checks[instance["truth"]]
            missed[key][verdict_of(check)] += 1
            if "--list" in sys.argv:
                print(f"{name} copy {instance['truth']}: visible {instance['visib_fract']:.2f}, true pose scores "
                      f"{check['score']:.2f} ({check['visible_support']:.2f} of what the scan could show), "
                      f"as found {check['as_found']}, as laid {check['as_laid']}")
    print(f"{'bins':<22} {'copies':>6} {'missed':>6} {'off':>4} " + " ".join(f"{v:>15}" for v in VERDICTS))
    for key in sorted(totals):
        m = missed[key]
        print(f"{key:<22} {totals[key]['copies']:>6} {sum(m.values()):>6} {totals[key]['off']:>4} "
              + " ".join(f"{m[v]:>15}" for v in VERDICTS))


if __name__ == "__main__":
    main()
