#!/usr/bin/env python3
"""An independent check of the KITTI excerpt's ground truth against two estimators that share
no code with segloc (OpenCV): the essential matrix of the left images and a stereo PnP
(SGBM disparity, pyramidal LK, solvePnPRansac + LM), beside segloc's `vo.tum`.

Usage: scripts/check_kitti_truth.py VO_TUM [SEQUENCE_DIR]
  VO_TUM: `segloc vo --kitti SEQUENCE_DIR -o VO_TUM`; SEQUENCE_DIR defaults to
  $SEGLOC_DATA/kitti-vo/sequence_1. Needs numpy and OpenCV (not project dependencies:
  `pip install numpy opencv-python-headless`).

Prints, for spans of frames, the rotation vector (degrees, camera axes x right, y down,
z forward) of the truth, of segloc and of the two OpenCV estimates; then the mean per-frame
rotation difference to the truth over frames 12-50 (docs/design/vo-kitti-truth.md).
"""
import os
import sys

import cv2
import numpy as np

TUM = sys.argv[1]
SEQ = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.environ.get("SEGLOC_DATA", "../shared/data"), "kitti-vo", "sequence_1")


def read_calibration():
    rows = [list(map(float, l.split()[-12:])) for l in open(os.path.join(SEQ, "calib.txt"))]
    p0, p1 = np.array(rows[0]).reshape(3, 4), np.array(rows[1]).reshape(3, 4)
    return p0[:, :3], -p1[0, 3] / p1[0, 0]


K, BASELINE = read_calibration()
image = lambda side, k: cv2.imread(os.path.join(SEQ, f"image_{side}", f"{k:06d}.png"), 0)
truth = [np.vstack([np.array(list(map(float, l.split()))).reshape(3, 4), [0, 0, 0, 1]])
         for l in open(os.path.join(SEQ, "poses.txt"))]


def read_tum(path):
    poses = []
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        v = list(map(float, line.split()))
        x, y, z, w = v[4:8]
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        t = np.eye(4)
        t[:3, :3], t[:3, 3] = r, v[1:4]
        poses.append(t)
    return poses


segloc = read_tum(TUM)
rotvec = lambda r: np.degrees(cv2.Rodrigues(r)[0].ravel())
relative = lambda poses, a, b: (np.linalg.inv(poses[a]) @ poses[b])[:3, :3]


def tracks(a, b):
    """Corners of frame a tracked (forward-backward checked) through to frame b."""
    start = cv2.goodFeaturesToTrack(image("l", a), 3000, 0.01, 8)
    first, points = start.copy(), start
    lk = dict(winSize=(21, 21), maxLevel=4)
    for k in range(a + 1, b + 1):
        nxt, st, _ = cv2.calcOpticalFlowPyrLK(image("l", k - 1), image("l", k), points, None, **lk)
        back, st2, _ = cv2.calcOpticalFlowPyrLK(image("l", k), image("l", k - 1), nxt, None, **lk)
        ok = (st.ravel() == 1) & (st2.ravel() == 1) & (
            np.linalg.norm((back - points).reshape(-1, 2), axis=1) < 0.5)
        first, points = first[ok], nxt[ok]
    return first.reshape(-1, 2), points.reshape(-1, 2)


def essential_rotation(a, b):
    """first_from_curr rotation chained from frame-to-frame essential matrices."""
    curr_from_first = np.eye(3)
    for k in range(a, b):
        p0, p1 = tracks(k, k + 1)
        e, mask = cv2.findEssentialMat(p0, p1, K, cv2.RANSAC, 0.999, 0.5)
        _, r, _, _ = cv2.recoverPose(e, p0, p1, K, mask=mask)
        curr_from_first = r @ curr_from_first
    return curr_from_first.T


SGBM = cv2.StereoSGBM_create(0, 128, 7, P1=8 * 49, P2=32 * 49, uniquenessRatio=10,
                             speckleWindowSize=100, speckleRange=2, mode=cv2.STEREO_SGBM_MODE_HH)


def pnp_rotation(a, b):
    """first_from_curr rotation of frame b against frame a's stereo points."""
    disparity = SGBM.compute(image("l", a), image("r", a)).astype(np.float32) / 16
    pa, pb = tracks(a, b)
    d = np.array([disparity[int(round(y)), int(round(x))] for x, y in pa])
    z = K[0, 0] * BASELINE / np.where(d > 2, d, np.nan)
    keep = np.isfinite(z) & (z < 60)
    pa, pb, z = pa[keep], pb[keep], z[keep]
    x = np.stack([(pa[:, 0] - K[0, 2]) * z / K[0, 0], (pa[:, 1] - K[1, 2]) * z / K[1, 1], z], 1)
    _, rvec, tvec, inliers = cv2.solvePnPRansac(x, pb, K, None, iterationsCount=500,
                                                reprojectionError=1.0)
    i = inliers.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(x[i], pb[i], K, None, rvec, tvec)
    return cv2.Rodrigues(rvec)[0].T


for a, b in [(0, 5), (0, 11), (5, 11)]:
    print(f"frames {a}-{b}: truth {rotvec(relative(truth, a, b)).round(3)} "
          f"segloc {rotvec(relative(segloc, a, b)).round(3)} "
          f"essential {rotvec(essential_rotation(a, b)).round(3)} "
          f"pnp {rotvec(pnp_rotation(a, b)).round(3)}")
axes = lambda r: np.degrees(np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2)
pnp_diff, segloc_diff = [], []
for k in range(12, len(truth)):
    g = relative(truth, k - 1, k)
    pnp_diff.append(axes(g.T @ pnp_rotation(k - 1, k)))
    segloc_diff.append(axes(g.T @ relative(segloc, k - 1, k)))
print("frames 12-50, per-frame rotation minus the truth's, mean (x, y, z) degrees:")
print("  OpenCV stereo PnP", np.mean(pnp_diff, 0).round(4), " segloc", np.mean(segloc_diff, 0).round(4))
