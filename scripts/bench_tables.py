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


def sensor_table(noisy, rows, full):
    """The sensor models' rows: README's short table, or docs/benchmarks.md's (`full`)."""
    if full:
        print("\n| input | noise mm | k | binpose ms | recall (> half visible) | precision | centroid / angle | OpenCV ms, recall, precision |")
        print("|---|---|---|---|---|---|---|---|")
    else:
        print("\n| input | binpose ms | recall (> half visible) | precision | centroid | OpenCV ms, recall |")
        print("|---|---|---|---|---|---|")
    for i in noisy:
        b, o = rows.get((i, "binpose")), rows.get((i, "opencv-sample"))
        if b is None:
            continue
        noise = f" {b['noise_mm']:.2f} | {b['k_normals']} |" if full else ""
        error = f"{b['centroid_mm']:.2f} mm / {b['angle_deg']:.1f}°" if full else f"{b['centroid_mm']:.2f} mm"
        peer = (f"{o['detect_ms_median']:.0f}, {pct(o['recall'])}" + (f", {pct(o['precision'])}" if full else "")) if o else "-"
        print(f"| {i} |{noise} {b['detect_ms_median']:.0f} | {pct(b['recall'])} ({pct(b['recall_over_half_visible'])}) "
              f"| {pct(b['precision'])} | {error} | {peer} |")


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

    sensor_table(noisy, rows, full=False)

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

    sensor_table(noisy, rows, full=True)

if __name__ == "__main__":
    main()
