#!/usr/bin/env python3
"""Why the stereo VO lost the frames it lost on a rendered drive: each lost frame's left
image and depth (from `segloc sim render`) sorted into what the camera could see.

    segloc vo --images DIR -o vo.tum --per-frame frames.csv
    python3 scripts/vo_lost_frames.py DIR frames.csv [--max-disparity-px 160]

Classes, in this order (the first that holds):
  no ground     under 5 % of the pixels see terrain (sky: the camera pitched up)
  too near      the median terrain depth is nearer than the stereo search reaches
                (fx * baseline / max_disparity_px)
  dark          the terrain's 90th percentile grey is under 40: all in shadow, only the
                ambient light and the noise (lit regolith is grey 100-200)
  textured      none of the above: the images held motion the VO did not recover
Prints one line per run of consecutive lost frames and the counts per class (needs numpy
and Pillow).
"""
import argparse
import csv
import json
import os

import numpy as np
from PIL import Image


def classify(left, depth_mm, near_limit_m):
    ground = depth_mm > 0
    if ground.mean() < 0.05:
        return "no ground", ground.mean(), float("nan")
    median_m = float(np.median(depth_mm[ground])) / 1000.0
    if median_m < near_limit_m:
        return "too near", ground.mean(), median_m
    if np.percentile(left[ground], 90) < 40:
        return "dark", ground.mean(), median_m
    return "textured", ground.mean(), median_m


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("render_dir")
    ap.add_argument("per_frame_csv")
    ap.add_argument("--max-disparity-px", type=float, default=160.0)
    args = ap.parse_args()
    calib = json.load(open(os.path.join(args.render_dir, "calibration.json")))
    near_limit_m = calib["fx"] * calib["baseline_m"] / args.max_disparity_px
    every = calib.get("every_ticks", 1)
    rows = list(csv.DictReader(open(args.per_frame_csv)))
    lost = [k for k, r in enumerate(rows) if r["lost"] == "1"]
    counts, runs = {}, []
    for k in lost:
        stem = os.path.join(args.render_dir, "%06d" % (k * every))
        left = np.asarray(Image.open(stem + "_0.png")).astype(float)
        depth = np.asarray(Image.open(stem + "_depth.png"))
        label, ground, median_m = classify(left, depth, near_limit_m)
        counts[label] = counts.get(label, 0) + 1
        if runs and runs[-1]["last"] == k - 1 and runs[-1]["label"] == label:
            runs[-1]["last"] = k
        else:
            runs.append({"first": k, "last": k, "label": label, "t": rows[k]["t"],
                         "ground": ground, "median_m": median_m})
    print(f"{len(lost)} lost of {len(rows)} frames; near limit {near_limit_m:.2f} m")
    for r in runs:
        print(f"  frames {r['first']}-{r['last']} (t {r['t']} s): {r['label']} "
              f"(first: terrain {100 * r['ground']:.1f} % of pixels, median depth "
              f"{r['median_m']:.2f} m)")
    print("counts:", ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


if __name__ == "__main__":
    main()
