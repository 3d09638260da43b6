#!/usr/bin/env python3
"""Synthetic 3D pose graphs (g2o) with the noise of the public "bignoise" variants.

The public hard 3D benchmarks (sphere_bignoise_vertex3, torus3D, grid3D) are not shipped by
any package this project can install; this script makes graphs of the same shapes:

* sphere: rings of poses on a sphere (as sphere2500: 50 rings of 50 poses, odometry along
  each ring and from ring to ring, and a loop closure from every pose to the one below it);
* torus: poses winding around a torus, each loop closing to the pose one winding back;
* grid: a snake path through an n x n x n grid of cells, driven twice, closing loops to
  every earlier pose in the same or a neighbouring cell (a fraction of them).

Every edge is the true relative pose perturbed by `Exp(n)`, n ~ N(0, diag(σ_R² I, σ_t² I))
in GTSAM's (rotation, translation) order with the perturbation on the right; the information
matrix written is the exact inverse covariance (g2o order: translation, then rotation). The
vertices are the chained noisy odometry, as in the public files. Default noise σ_R = 0.1 rad
(5.7° per edge) and σ_t = 0.1 m; `--rot-sigma 0.01` gives a "smallnoise"-like graph.

Usage: gen_posegraph.py {sphere,torus,grid} -o OUT.g2o [--size N] [--seed S]
       [--rot-sigma R] [--trans-sigma T]
"""

import argparse
import math
import sys

import numpy as np


def hat(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def exp_so3(w):
    th = np.linalg.norm(w)
    k = hat(w)
    if th < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + math.sin(th) / th * k + (1 - math.cos(th)) / th**2 * k @ k


def exp_se3(xi):
    """GTSAM Pose3::Expmap of (ω, v): rotation and translation J_l(ω) v."""
    w, v = xi[:3], xi[3:]
    th = np.linalg.norm(w)
    k = hat(w)
    if th < 1e-12:
        jac = np.eye(3) + 0.5 * k
    else:
        jac = np.eye(3) + (1 - math.cos(th)) / th**2 * k + (th - math.sin(th)) / th**3 * k @ k
    return exp_so3(w), jac @ v


def compose(a, b):
    return a[0] @ b[0], a[0] @ b[1] + a[1]


def between(a, b):
    return a[0].T @ b[0], a[0].T @ (b[1] - a[1])


def look_rotation(forward, up_hint):
    """Rotation whose x axis is `forward` and z axis as close to `up_hint` as possible."""
    x = forward / np.linalg.norm(forward)
    y = np.cross(up_hint, x)
    if np.linalg.norm(y) < 1e-9:
        y = np.cross([1.0, 0, 0], x) if abs(x[0]) < 0.9 else np.cross([0, 1.0, 0], x)
    y /= np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)])


def sphere(size):
    """size rings of size poses; closures to the pose one ring down."""
    poses, edges = [], []
    radius = 50.0
    for ring in range(size):
        polar = math.pi * (ring + 1) / (size + 1)
        for k in range(size):
            az = 2 * math.pi * k / size
            p = radius * np.array([math.sin(polar) * math.cos(az), math.sin(polar) * math.sin(az), -math.cos(polar)])
            tangent = np.array([-math.sin(az), math.cos(az), 0.0])
            poses.append((look_rotation(tangent, p / radius), p))
    n = len(poses)
    edges += [(i, i + 1) for i in range(n - 1)]
    edges += [(i - size, i) for i in range(size, n)]
    return poses, edges


def torus(size):
    """A path winding `size` times around the tube of a torus, `size` poses per winding."""
    poses, edges = [], []
    big, small = 30.0, 10.0
    n = size * size
    for i in range(n):
        u = 2 * math.pi * i / n  # around the torus
        v = 2 * math.pi * i / size  # around the tube
        centre = np.array([big * math.cos(u), big * math.sin(u), 0.0])
        normal = np.array([math.cos(v) * math.cos(u), math.cos(v) * math.sin(u), math.sin(v)])
        p = centre + small * normal
        du = 2 * math.pi / n
        dv = 2 * math.pi / size
        tangent = (np.array([-big * math.sin(u), big * math.cos(u), 0.0]) * du
                   + small * np.array([-math.sin(v) * math.cos(u), -math.sin(v) * math.sin(u), math.cos(v)]) * dv)
        poses.append((look_rotation(tangent, normal), p))
    edges += [(i, i + 1) for i in range(n - 1)]
    edges += [(i - size, i) for i in range(size, n)]
    return poses, edges


def grid(size, rng):
    """A snake path through size³ cells, driven twice; closures to earlier neighbours."""
    cells = []
    for z in range(size):
        for yy in range(size):
            y = yy if z % 2 == 0 else size - 1 - yy
            for xx in range(size):
                x = xx if (y + z * size) % 2 == 0 else size - 1 - xx
                cells.append((x, y, z))
    path = cells + cells[::-1]
    poses = []
    for i, c in enumerate(path):
        nxt = path[i + 1] if i + 1 < len(path) else path[i - 1]
        d = np.array(nxt, float) - np.array(c, float)
        if np.linalg.norm(d) < 1e-9:
            d = np.array([1.0, 0, 0])
        poses.append((look_rotation(d, np.array([0, 0, 1.0])), 2.0 * np.array(c, float)))
    n = len(poses)
    edges = [(i, i + 1) for i in range(n - 1)]
    seen = {}
    for j, c in enumerate(path):
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    if abs(dx) + abs(dy) + abs(dz) > 1:
                        continue
                    for i in seen.get((c[0] + dx, c[1] + dy, c[2] + dz), []):
                        if j - i > 1 and rng.random() < 0.5:
                            edges.append((i, j))
        seen.setdefault(c, []).append(j)
    return poses, edges


def quaternion(r):
    """(qx, qy, qz, qw) of a rotation matrix."""
    t = np.trace(r)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        return ((r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s)
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k]) * 2
    q = [0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (r[j, i] + r[i, j]) / s
    q[k] = (r[k, i] + r[i, k]) / s
    return q[0], q[1], q[2], (r[k, j] - r[j, k]) / s


def fields(pose):
    qx, qy, qz, qw = quaternion(pose[0])
    t = pose[1]
    return f"{t[0]:.9g} {t[1]:.9g} {t[2]:.9g} {qx:.12g} {qy:.12g} {qz:.12g} {qw:.12g}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shape", choices=["sphere", "torus", "grid"])
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--size", type=int, help="rings (sphere), windings (torus), cells per side (grid)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rot-sigma", type=float, default=0.1, help="rotation noise per edge (rad)")
    ap.add_argument("--trans-sigma", type=float, default=0.1, help="translation noise per edge (m)")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    if args.shape == "sphere":
        poses, edges = sphere(args.size or 50)
    elif args.shape == "torus":
        poses, edges = torus(args.size or 60)
    else:
        poses, edges = grid(args.size or 10, rng)
    sigma = np.array([args.rot_sigma] * 3 + [args.trans_sigma] * 3)
    info_g2o = np.diag(1.0 / np.concatenate([sigma[3:], sigma[:3]]) ** 2)  # (t, R) order
    upper = " ".join(f"{info_g2o[a, b]:.9g}" for a in range(6) for b in range(a, 6))
    measured = {}
    for i, j in edges:
        r, t = exp_se3(rng.normal(size=6) * sigma)
        measured[(i, j)] = compose(between(poses[i], poses[j]), (r, t))
    # Vertices: chained noisy odometry from the true first pose.
    est = [poses[0]]
    for i in range(len(poses) - 1):
        est.append(compose(est[-1], measured[(i, i + 1)]))
    with open(args.output, "w") as f:
        for i, p in enumerate(est):
            f.write(f"VERTEX_SE3:QUAT {i} {fields(p)}\n")
        for i, j in edges:
            f.write(f"EDGE_SE3:QUAT {i} {j} {fields(measured[(i, j)])} {upper}\n")
    print(f"{args.output}: {len(poses)} poses, {len(edges)} edges, sigma_R {args.rot_sigma} rad, "
          f"sigma_t {args.trans_sigma} m", file=sys.stderr)


if __name__ == "__main__":
    main()
