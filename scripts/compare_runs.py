#!/usr/bin/env python3
"""Compares two bench_e2e result files row for row: the same inputs and methods must give the
same detections (poses within --tol mm / matrix entry). Exit 1 on any difference.

  scripts/compare_runs.py before.json after.json [--tol 1e-3] [--method-map binpose-fast=binpose]
"""
import argparse
import json
import sys


def rows(path):
    with open(path) as f:
        return {(r["input"], r["method"]): r for r in json.load(f)["rows"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--method-map", action="append", default=[],
                    help="OLD=NEW: compare the before file's OLD method with the after file's NEW")
    a = ap.parse_args()
    mapping = dict(m.split("=", 1) for m in a.method_map)
    before, after = rows(a.before), rows(a.after)
    bad = 0
    compared = 0
    for (inp, method), b in sorted(before.items()):
        key = (inp, mapping.get(method, method))
        if key not in after or "poses" not in b:
            continue
        p, q = b["poses"], after[key].get("poses", [])
        compared += 1
        diff = len(p) != len(q) or any(abs(x - y) > a.tol for r, s in zip(p, q) for x, y in zip(r, s))
        status = "DIFFERENT" if diff else "same"
        bad += diff
        print(f"{inp:<10} {method:<16} -> {key[1]:<16} {len(p):>3} / {len(q):>3} poses  {status}")
    print(f"{compared} rows compared, {bad} different")
    return 1 if bad or compared == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
