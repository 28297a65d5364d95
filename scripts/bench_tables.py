#!/usr/bin/env python3
"""Prints the Markdown tables of README.md and docs/benchmarks.md from one bench_e2e result file
(build/bench/binpose_bench_e2e ... --out FILE): the clean inputs' and the sensor models' tables.

  scripts/bench_tables.py bench/results.json
"""
import json
import sys

NOISY = ("-sl", "-ind", "-tof")


def pct(x):
    return f"{round(100 * x)}%"


def main():
    with open(sys.argv[1]) as f:
        data = json.load(f)
    rows = {(r["input"], r["method"]): r for r in data["rows"]}
    inputs = list(dict.fromkeys(r["input"] for r in data["rows"]))
    speedup = {r["input"]: r["speedup"] for r in data["ratios"]}
    clean = [i for i in inputs if not i.endswith(NOISY)]
    noisy = [i for i in inputs if i.endswith(NOISY)]
    print(f"machine: {data.get('machine', '?')}, threads {data.get('threads', '?')}, repeats {data.get('repeats', '?')}\n")

    print("| input | binpose ms | recall (> half visible) | precision | centroid / angle | thesis preset ms, recall, precision | OpenCV ms, recall, precision | speed-up |")
    print("|---|---|---|---|---|---|---|---|")
    for i in clean:
        b, t, o = rows.get((i, "binpose")), rows.get((i, "binpose-thesis")), rows.get((i, "opencv-sample"))
        if b is None:
            continue
        peer = lambda r: f"{r['detect_ms_median']:.0f}, {pct(r['recall'])}, {pct(r['precision'])}" if r else "-"
        print(f"| {i} | {b['detect_ms_median']:.0f} | {pct(b['recall'])} ({pct(b['recall_over_half_visible'])}) | {pct(b['precision'])} "
              f"| {b['centroid_mm']:.2f} mm / {b['angle_deg']:.2f}° | {peer(t)} | {peer(o)} | {speedup.get(i, float('nan')):.1f}x |")

    print("\n| input | binpose ms | recall (> half visible) | precision | centroid | OpenCV ms, recall |")
    print("|---|---|---|---|---|---|")
    for i in noisy:
        b, o = rows.get((i, "binpose")), rows.get((i, "opencv-sample"))
        if b is None:
            continue
        peer = f"{o['detect_ms_median']:.0f}, {pct(o['recall'])}" if o else "-"
        print(f"| {i} | {b['detect_ms_median']:.0f} | {pct(b['recall'])} ({pct(b['recall_over_half_visible'])}) | {pct(b['precision'])} "
              f"| {b['centroid_mm']:.2f} mm | {peer} |")

    print("\n| input | method | detect ms | train ms | found | recall | > half visible | precision | centroid mm | angle ° | peak MiB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for i in clean:
        for m in ("binpose", "binpose-thesis", "opencv-sample"):
            r = rows.get((i, m))
            if r is None:
                continue
            print(f"| {i} | {m} | {r['detect_ms_median']:.1f} | {r['train_ms']:.0f} | {r['found']}/{r['instances']} | {pct(r['recall'])} "
                  f"| {pct(r['recall_over_half_visible'])} | {pct(r['precision'])} | {r['centroid_mm']:.2f} | {r['angle_deg']:.2f} "
                  f"| {r['peak_above_input_mib']:.0f} |")

    print("\n| input | noise mm | k | binpose ms | recall (> half visible) | precision | centroid / angle | OpenCV ms, recall, precision |")
    print("|---|---|---|---|---|---|---|---|")
    for i in noisy:
        b, o = rows.get((i, "binpose")), rows.get((i, "opencv-sample"))
        if b is None:
            continue
        peer = f"{o['detect_ms_median']:.0f}, {pct(o['recall'])}, {pct(o['precision'])}" if o else "-"
        print(f"| {i} | {b['noise_mm']:.2f} | {b['k_normals']} | {b['detect_ms_median']:.0f} | {pct(b['recall'])} "
              f"({pct(b['recall_over_half_visible'])}) | {pct(b['precision'])} | {b['centroid_mm']:.2f} mm / {b['angle_deg']:.1f}° | {peer} |")


if __name__ == "__main__":
    main()
