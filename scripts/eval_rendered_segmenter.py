#!/usr/bin/env python3
"""A segmenter through `segloc detect` on held-out rendered frames (`segloc sim render`),
against the renderer's truth: instance recall of the rocks >= 10 cm (diameter) within 6 m
that do not touch the image border and show at least 30 % of their silhouette, precision of the boulders within 6 m, and the median
error of the boulder centroids (camera frame) against the rocks' visible-surface centres.

A boulder is matched to the rock whose instance id is under its pixel centroid (or the
most frequent rock id within 3 px of it). Needs numpy and pillow.

usage: python3 scripts/eval_rendered_segmenter.py SEGLOC_BIN SEGMENTER DIR [DIR ...] [--json]
"""
import json
import subprocess
import sys

import numpy as np
from PIL import Image

MIN_DIAMETER_M, MAX_RANGE_M, RADIUS_PX = 0.10, 6.0, 3


def quat_to_matrix(qx, qy, qz, qw):
    return np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )


def frames_of(d):
    rocks = json.load(open(f"{d}/rocks.json"))
    poses = {}
    for line in open(f"{d}/truth.tum"):
        if line.startswith("#") or not line.strip():
            continue
        t, x, y, z, qx, qy, qz, qw = map(float, line.split())
        poses[round(t / 0.05)] = (np.array([x, y, z]), quat_to_matrix(qx, qy, qz, qw))
    for f in rocks["frames"]:
        yield f, poses[f["frame"]]


def evaluate(binary, segmenter, dirs):
    tp = fn = det_tp = det_fp = 0
    errors, times = [], []
    for d in dirs:
        for f, (t_wc, r_wc) in frames_of(d):
            stem = f"{d}/{f['frame']:06d}"
            ids = np.asarray(Image.open(f"{stem}_ids.png")).astype(np.int64)
            depth = np.asarray(Image.open(f"{stem}_depth.png")).astype(np.float64) / 1000.0
            h, w = ids.shape
            out = subprocess.run(
                [binary, "detect", "--segmenter", segmenter, "--json", "--left", f"{stem}_0.png", "--right", f"{stem}_1.png"],
                capture_output=True, text=True, check=True,
            )
            rep = json.loads(out.stdout)
            times.append(rep["timing"]["segment_ms"])
            matched = {}
            for b in rep["boulders"]:
                u, v = b["pixel_centroid"]
                ui, vi = int(round(u)), int(round(v))
                win = ids[max(vi - RADIUS_PX, 0) : vi + RADIUS_PX + 1, max(ui - RADIUS_PX, 0) : ui + RADIUS_PX + 1]
                win = win[(win > 0) & (win < 65535)]
                rid = int(ids[min(vi, h - 1), min(ui, w - 1)]) if 0 < ids[min(vi, h - 1), min(ui, w - 1)] < 65535 else (
                    int(np.bincount(win).argmax()) if win.size else 0)
                if b["depth_m"] > MAX_RANGE_M:
                    continue
                if rid:
                    det_tp += 1
                    matched.setdefault(rid - 1, b)
                else:
                    det_fp += 1
            for r in f["visible"]:
                mask = ids == r["id"] + 1
                if not mask.any() or 2 * r["radius_m"] < MIN_DIAMETER_M or r["visible_fraction"] < 0.3:
                    continue
                ys, xs = np.nonzero(mask)
                if xs.min() <= 2 or ys.min() <= 2 or xs.max() >= w - 3 or ys.max() >= h - 3:
                    continue
                if np.median(depth[mask]) > MAX_RANGE_M:
                    continue
                b = matched.get(r["id"])
                if b is None:
                    fn += 1
                    continue
                tp += 1
                p_cam = r_wc.T @ (np.array(r["visible_center_world"]) - t_wc)
                errors.append(float(np.linalg.norm(np.array(b["position_camera"]) - p_cam)))
    return {
        "segmenter": segmenter,
        "frames": len(times),
        "rocks": tp + fn,
        "recall": tp / max(tp + fn, 1),
        "precision": det_tp / max(det_tp + det_fp, 1),
        "boulders_within_6m": det_tp + det_fp,
        "centroid_error_median_m": float(np.median(errors)) if errors else None,
        "mean_segment_ms": float(np.mean(times)) if times else None,
    }


def main():
    args = [a for a in sys.argv[1:] if a != "--json"]
    if len(args) < 3:
        sys.exit(__doc__)
    r = evaluate(args[0], args[1], args[2:])
    if "--json" in sys.argv:
        print(json.dumps(r))
    else:
        for k, v in r.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
