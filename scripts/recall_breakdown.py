#!/usr/bin/env python3
"""Tables of why the front end misses rendered rocks, from `segloc eval render --breakdown FILE`.

usage: scripts/recall_breakdown.py BREAKDOWN.jsonl [more.jsonl ...]

Prints (markdown): the causes of the misses by range band and by size band, and the
figures of the counted rocks (protrusion, stereo, estimated height) detected vs missed.
"""
import json
import statistics
import sys


def load(paths):
    rows = []
    for p in paths:
        with open(p) as f:
            rows += [json.loads(line) for line in f if line.strip()]
    return rows


def band(value, edges):
    for lo, hi in zip(edges, edges[1:]):
        if lo <= value < hi:
            return f"{lo:g}-{hi:g}"
    return f">={edges[-1]:g}"


def table(rows, key, bands, title):
    causes = sorted({r["cause"] for r in rows}, key=lambda c: -sum(r["cause"] == c for r in rows))
    print(f"\n| cause ({title}) | " + " | ".join(bands) + " | all |")
    print("|---" * (len(bands) + 2) + "|")
    for c in causes:
        cells = [sum(1 for r in rows if r["cause"] == c and key(r) == b) for b in bands]
        print(f"| {c} | " + " | ".join(str(x) for x in cells) + f" | {sum(cells)} ({sum(cells) / len(rows):.1%}) |")
    totals = [sum(1 for r in rows if key(r) == b) for b in bands]
    print("| rocks | " + " | ".join(str(x) for x in totals) + f" | {len(rows)} |")


def med(values):
    v = [x for x in values if x is not None and x == x]
    return statistics.median(v) if v else float("nan")


def main():
    rows = load(sys.argv[1:])
    if not rows:
        sys.exit("no rows")
    ranges = ["0-2", "2-4", "4-6"]
    sizes = ["0.1-0.15", "0.15-0.2", "0.2-0.4", ">=0.4"]
    table(rows, lambda r: band(r["range_m"], [0, 2, 4, 6]), ranges, "range m")
    table(rows, lambda r: band(r["size_m"], [0.1, 0.15, 0.2, 0.4]), sizes, "size m")
    print("\n| rocks | n | protrusion cm | seed threshold cm | est. peak height cm | valid disparity | depth error cm | shadow frac | region cover |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, sel in (("detected", [r for r in rows if r["detected"]]), ("missed", [r for r in rows if not r["detected"]])):
        print(f"| {name} | {len(sel)} | {100 * med(r['protrusion_m'] for r in sel):.1f} | "
              f"{100 * med(r['seed_threshold_m'] for r in sel):.1f} | {100 * med(r['peak_height_m'] for r in sel):.1f} | "
              f"{med(r['valid_fraction'] for r in sel):.2f} | {100 * med(r['depth_error_m'] for r in sel):.1f} | "
              f"{med(r['shadow_fraction'] for r in sel):.2f} | {med(r['region_cover'] for r in sel):.2f} |")
    low = [r for r in rows if r["protrusion_m"] < 0.02]
    print(f"\nrocks protruding < 2 cm: {len(low)} of {len(rows)}; < 5 cm: "
          f"{sum(r['protrusion_m'] < 0.05 for r in rows)}; recall {sum(r['detected'] for r in rows) / len(rows):.3f}")


if __name__ == "__main__":
    main()
