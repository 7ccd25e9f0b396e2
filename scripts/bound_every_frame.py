#!/usr/bin/env python3
"""The reported bound against the measured error on every frame (docs/plan-time.md): joins a `fly --json
--error-every 1` report with its `--csv` by frame and prints, for one flight, the frames measured, the
worst ratio measured / max(epsilon, unmet_px) and its frame, and the frames past 1 (the bound broken).
Usage: bound_every_frame.py EPSILON REPORT.json REPORT.csv"""
import csv
import json
import sys

eps = float(sys.argv[1])
report = json.load(open(sys.argv[2]))
unmet = {int(r["frame"]): float(r["unmet_px"]) for r in csv.DictReader(open(sys.argv[3]))}
worst, at, over = 0.0, None, []
frames = report["screen_error_sampled"]["per_frame"]
for r in frames:
    f, px = r["frame"], r["max_px"]
    bound = max(eps, unmet[f])
    ratio = px / bound
    if ratio > worst:
        worst, at = ratio, f
    if ratio > 1.0:
        over.append(f"{f}: {px:.2f}/{bound:.2f}")
print(f"{len(frames)}\t{worst:.3f}\t{at}\t{len(over)}\t{' '.join(over)}\t{report['plan_run_hash']}")
