#!/usr/bin/env python3
"""Stereo depth at hand-labelled pixels of the real LAC pairs (a help to judge range while
labelling, see tests/fixtures/README.md): zero-mean SAD block matching of a 15 × 15 window
of the left image along the same row of the right image, disparities 1–160 px, sub-pixel
by a parabola; depth = fx · baseline / disparity (fx 914.015 px, baseline 0.162 m).

usage: python3 scripts/label_depths.py LABELS.csv DATA_DIR > with_depths.csv
   (needs numpy and pillow; prints the CSV with a stereo_depth_m column added)
"""
import csv
import sys

import numpy as np
from PIL import Image

FX, BASELINE, HALF, DMAX = 914.015, 0.162, 7, 160


def depth_at(left, right, u, v):
    h, w = left.shape
    u, v = int(round(u)), int(round(v))
    if v - HALF < 0 or v + HALF >= h or u - HALF < 0 or u + HALF >= w:
        return None
    patch = left[v - HALF : v + HALF + 1, u - HALF : u + HALF + 1]
    patch = patch - patch.mean()
    costs = []
    for d in range(1, DMAX):
        if u - d - HALF < 0:
            break
        cand = right[v - HALF : v + HALF + 1, u - d - HALF : u - d + HALF + 1]
        costs.append(np.abs(patch - (cand - cand.mean())).sum())
    if len(costs) < 3:
        return None
    c = np.array(costs)
    k = int(c.argmin())
    d = k + 1.0
    if 0 < k < len(c) - 1:
        denom = c[k - 1] - 2 * c[k] + c[k + 1]
        if denom > 0:
            d += 0.5 * (c[k - 1] - c[k + 1]) / denom
    return FX * BASELINE / d


def main():
    labels, data = sys.argv[1], sys.argv[2]
    rows = list(csv.DictReader(line for line in open(labels) if not line.startswith("#")))
    cache = {}
    out = csv.writer(sys.stdout)
    fields = list(rows[0].keys()) + ["stereo_depth_m"]
    out.writerow(fields)
    for r in rows:
        p = r["pair"]
        if p not in cache:
            load = lambda s: np.asarray(Image.open(f"{data}/lac-images/{p}_{s}.png").convert("L"), np.float32)
            cache[p] = (load(0), load(1))
        z = depth_at(*cache[p], float(r["u"]), float(r["v"]))
        out.writerow([r[f] for f in fields[:-1]] + ["" if z is None else f"{z:.2f}"])


if __name__ == "__main__":
    main()
