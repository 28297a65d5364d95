#!/usr/bin/env python3
"""Markdown tables of thesis-style sweeps (binpose sweep --thesis-scenes) for
docs/thesis_reproduction.md: per parameter combination, recall, precision, the share of matches
that are the part turned over (angle > 90 degrees: ADD-S under a tenth of the diameter accepts
them for a shallow or nearly symmetric part), the median and mean centroid and angular errors of
the other matches, and time per object.
    scripts/thesis_tables.py SWEEP_DIR[:PARAM] ...   (PARAM: one row per value, pooled over the rest)"""
import csv
import statistics
import sys
from collections import defaultdict

META = {"scene", "instance", "visible_fraction", "visib_fract", "found", "centroid_mm", "angle_deg"}


def table(folder, by=None):
    instances = list(csv.DictReader(open(f"{folder}/instances.csv")))
    results = list(csv.DictReader(open(f"{folder}/results.csv")))
    names = [k for k in results[0] if k in instances[0] and k not in META]
    if by:  # pooled over the other parameters
        names = [by]
    by = defaultdict(lambda: {"matches": [], "visible": [0, 0], "detections": 0, "found": 0, "instances": 0, "ms": 0.0})
    for row in instances:
        key = tuple(row[n] for n in names)
        g = by[key]
        if float(row["visib_fract"]) > 0.5:
            g["visible"][0] += 1
            g["visible"][1] += row["found"] == "1"
        if row["found"] == "1":
            g["matches"].append((float(row["centroid_mm"]), float(row["angle_deg"])))
    for row in results:
        g = by[tuple(row[n] for n in names)]
        g["detections"] += int(row["detections"])
        g["found"] += int(row["found"])
        g["instances"] += int(row["instances"])
        g["ms"] += float(row["total_ms"])
    head = names + ["recall", "recall (visib > 0.5)", "precision", "centroid mm: median / mean", "angle deg: median / mean",
                    "turned over", "ms / object"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for key, g in sorted(by.items(), key=lambda kv: [float(v) for v in kv[0]]):
        upright = [m for m in g["matches"] if m[1] <= 90]
        c = [m[0] for m in upright]
        a = [m[1] for m in upright]
        cells = list(key) + [
            f"{g['found'] / g['instances']:.0%}", f"{g['visible'][1] / max(1, g['visible'][0]):.0%}",
            f"{g['found'] / max(1, g['detections']):.0%}",
            f"{statistics.median(c):.2f} / {statistics.mean(c):.2f}",
            f"{statistics.median(a):.1f} / {statistics.mean(a):.1f}",
            f"{1 - len(upright) / len(g['matches']):.0%}", f"{g['ms'] / max(1, g['found']):.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    for arg in sys.argv[1:]:  # FOLDER, or FOLDER:PARAM to pool over every parameter but PARAM
        folder, _, by = arg.partition(":")
        print(f"`{arg}`\n\n{table(folder, by or None)}\n")
