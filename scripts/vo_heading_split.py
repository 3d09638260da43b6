#!/usr/bin/env python3
"""The rotation drift of a rendered drive split into heading and tilt, for the VO, the gyro
alone, and the gyro with its bias estimated from the VO (issue 27; docs/design/vo-gyro-heading.md).

Usage: scripts/vo_heading_split.py RENDER_DIR VO_TUM [TAU_S ...]
  RENDER_DIR as `segloc sim render` writes it (truth.tum, imu.csv, calibration.json);
  VO_TUM from `segloc vo --images RENDER_DIR -o VO_TUM` (one pose per rendered frame).
Per 10 m segment (every 10th frame, as `segloc eval vo`): the mean change of the heading
error (about the world's vertical), of the tilt error, and the mean total rotation error.
For each TAU_S (default 120): the gyro integrated with the bias subtracted, the bias being an
average of gyro − VO rates (a plain mean for the first TAU_S seconds, exponential after), and
the VO with only its heading increments replaced by that gyro's (what `gyro_heading` does).
"""
import json
import sys

import numpy as np


def rotation(x, y, z, w):
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def log_so3(r):
    angle = np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return v * (angle / (2 * np.sin(angle))) if angle > 1e-9 else v / 2


def exp_so3(v):
    angle = np.linalg.norm(v)
    if angle < 1e-12:
        return np.eye(3)
    k = v / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def load_tum(path):
    rows = [l.split() for l in open(path) if l.strip() and not l.startswith('#')]
    t = np.array([float(r[0]) for r in rows])
    p = np.array([[float(v) for v in r[1:4]] for r in rows])
    return t, p, [rotation(*map(float, r[4:8])) for r in rows]


def main():
    render, vo_path = sys.argv[1], sys.argv[2]
    taus = [float(a) for a in sys.argv[3:]] or [120.0]
    t, p, truth = load_tum(f'{render}/truth.tum')
    _, _, vo = load_tum(vo_path)
    calib = json.load(open(f'{render}/calibration.json'))
    mount = rotation(*calib['rover_from_left_camera']['quaternion_xyzw'])
    imu = [l.strip().split(',') for l in open(f'{render}/imu.csv')][1:]
    gyro = np.array([mount.T @ np.array([float(v) for v in r[5:8]]) for r in imu])
    n = min(len(t), len(vo))
    dist = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p[:n], axis=0), axis=1))])

    def split(first_from_camera):
        world = [truth[0] @ r for r in first_from_camera[:n]]
        err = np.array([log_so3(world[k] @ truth[k].T) for k in range(n)])
        heading, tilt, total = [], [], []
        for i in range(0, n, 10):
            j = np.searchsorted(dist, dist[i] + 10)
            if j >= n:
                break
            heading.append(abs(err[j, 2] - err[i, 2]))
            tilt.append(np.linalg.norm(err[j, :2] - err[i, :2]))
            rel = (truth[i].T @ truth[j]).T @ (first_from_camera[i].T @ first_from_camera[j])
            total.append(np.linalg.norm(log_so3(rel)))
        return tuple(np.degrees(np.mean(x)) for x in (heading, tilt, total))

    row = '{:<28} heading {:.4f}  tilt {:.4f}  total {:.4f} deg per 10 m'
    print(f'{render}: {n} frames, {dist[-1]:.1f} m')
    print(row.format('VO', *split(vo)))
    alone = [np.eye(3)]
    for k in range(1, n):
        alone.append(alone[-1] @ exp_so3(gyro[k] * (t[k] - t[k - 1])))
    print(row.format('gyro alone', *split(alone)))
    up = truth[0].T @ np.array([0.0, 0.0, 1.0])
    for tau in taus:
        bias, seen, h = np.zeros(3), 0.0, 0.0
        corrected, fused = [np.eye(3)], [vo[0]]
        for k in range(1, n):
            dt = t[k] - t[k - 1]
            image = log_so3(vo[k - 1].T @ vo[k])
            diff = gyro[k] - image / dt
            if np.linalg.norm(diff) < 0.01:
                seen += dt
                bias += max(dt / seen, dt / tau) * (diff - bias)
            corrected.append(corrected[-1] @ exp_so3((gyro[k] - bias) * dt))
            h += up @ (vo[k - 1] @ ((gyro[k] - bias) * dt)) - up @ (vo[k - 1] @ image)
            fused.append(exp_so3(up * h) @ vo[k])
        print(row.format(f'gyro - bias (tau {tau:g} s)', *split(corrected)))
        print(row.format(f'VO, gyro heading (tau {tau:g} s)', *split(fused)))


if __name__ == '__main__':
    main()
