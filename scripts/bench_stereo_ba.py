#!/usr/bin/env python3
"""Stereo bundle adjustment of issue 27 against GTSAM (run through scripts/bench_stereo_ba.sh).

GTSAM's StereoVOExample_large problem from the gtsam wheel's Data/ (VO_calibration.txt,
VO_camera_poses_large.txt, VO_stereo_factors_large.txt): one GenericStereoFactor per line
(1 px isotropic noise), landmarks initialised from their first observing camera, the first
pose held by NonlinearEquality, Levenberg–Marquardt with default parameters. segloc solves the
same problem with `segloc graph stereo-ba`. The files print rotations to 6 digits, so they are
not quite orthonormal; GTSAM (matrix Rot3) would keep them as they are, segloc projects them
onto SO(3): GTSAM is given the projected rotations here, so that both solve the same problem.
Both run on one thread pinned to the same core, runs alternating; times exclude file reading
and graph building (GTSAM: optimizer construction and optimize(); segloc: its report's time_ms).
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import numpy as np
import gtsam

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_section import write_section  # noqa: E402

SECTION = "## Stereo bundle adjustment vs GTSAM (issue 27)"
FILES = ("VO_calibration.txt", "VO_camera_poses_large.txt", "VO_stereo_factors_large.txt")


def data_file(name):
    path = os.path.join(os.path.dirname(gtsam.__file__), "Data", name)
    if not os.path.exists(path):
        sys.exit(f"{path} not found in the gtsam package")
    return path


def projected_pose(m):
    """Pose3 of a 4x4 matrix with its rotation projected onto SO(3) (as segloc reads it)."""
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return gtsam.Pose3(gtsam.Rot3(r), m[:3, 3])


def gtsam_problem(cal_path, poses_path, factors_path):
    cal = gtsam.Cal3_S2Stereo(*map(float, open(cal_path).read().split()))
    poses, first = {}, None
    for line in open(poses_path):
        t = line.split()
        if t:
            poses[int(t[0])] = projected_pose(np.array(list(map(float, t[1:17]))).reshape(4, 4))
            first = int(t[0]) if first is None else first
    graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
    for i, p in poses.items():
        initial.insert(gtsam.symbol("x", i), p)
    noise = gtsam.noiseModel.Isotropic.Sigma(3, 1.0)
    for line in open(factors_path):
        t = line.split()
        if not t:
            continue
        x, l = int(t[0]), int(t[1])
        ul, ur, v, px, py, pz = map(float, t[2:8])
        graph.add(gtsam.GenericStereoFactor3D(gtsam.StereoPoint2(ul, ur, v), noise,
                                              gtsam.symbol("x", x), gtsam.symbol("l", l), cal))
        if not initial.exists(gtsam.symbol("l", l)):
            initial.insert(gtsam.symbol("l", l), poses[x].transformFrom(np.array([px, py, pz])))
    graph.add(gtsam.NonlinearEqualityPose3(gtsam.symbol("x", first), poses[first]))
    return graph, initial


def run_gtsam(graph, initial):
    t0 = time.perf_counter()
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, gtsam.LevenbergMarquardtParams())
    result = optimizer.optimize()
    ms = (time.perf_counter() - t0) * 1e3
    return graph.error(result), optimizer.iterations(), ms


def run_segloc(binary, pin, paths):
    cmd = [*pin, binary, "graph", "stereo-ba", "--calibration", paths[0], "--poses", paths[1],
           "--factors", paths[2], "--json"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True,
                         env={**os.environ, "RAYON_NUM_THREADS": "1"})
    return json.loads(out.stdout)


def machine():
    try:
        for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
            if line.startswith("Model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--segloc", required=True)
    ap.add_argument("--benchmarks", required=True)
    ap.add_argument("--runs", type=int, default=11)
    ap.add_argument("--cpu", type=int, default=0)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    pin = ["taskset", "-c", str(args.cpu)] if subprocess.run(
        ["which", "taskset"], capture_output=True).returncode == 0 else []
    if pin:
        os.sched_setaffinity(0, {args.cpu})
    paths = [data_file(f) for f in FILES]
    graph, initial = gtsam_problem(*paths)
    gt_initial = graph.error(initial)
    rows = []
    for _ in range(args.runs):
        cost, iters, ms = run_gtsam(graph, initial)
        seg = run_segloc(args.segloc, pin, paths)
        rows.append({"gtsam_cost": cost, "gtsam_iters": iters, "gtsam_ms": ms, "segloc": seg})
    seg0 = rows[-1]["segloc"]
    gt_cost = rows[-1]["gtsam_cost"]
    rel = (seg0["final_cost"] - gt_cost) / gt_cost
    ratios = [r["gtsam_ms"] / r["segloc"]["time_ms"] for r in rows]
    gt_ms = statistics.median(r["gtsam_ms"] for r in rows)
    seg_ms = statistics.median(r["segloc"]["time_ms"] for r in rows)
    speedup = statistics.median(ratios)
    met = abs(rel) <= 1e-6 or seg0["final_cost"] < gt_cost
    date = subprocess.run(["date", "-u", "+%Y-%m-%d %H:%M UTC"], capture_output=True, text=True).stdout.strip()
    lines = [
        SECTION, "",
        f"Command: `scripts/bench_stereo_ba.sh --runs {args.runs}` — {date}, machine `{machine()}` "
        f"({os.cpu_count()} cores, shared; load average {os.getloadavg()[0]:.1f}), gtsam from PyPI; one thread each "
        f"pinned to CPU {args.cpu}, runs alternating; GTSAM's `StereoVOExample_large` "
        f"({seg0['poses']} poses, {seg0['landmarks']} landmarks, {seg0['factors']} stereo factors, 1 px, first pose fixed), "
        "rotations of the pose file projected onto SO(3) for both; cost in GTSAM's convention; times exclude reading.",
        "",
        "| solver | initial cost | final cost | iterations | median time (ms) | speed-up (median of per-run GTSAM/segloc) |",
        "|---|---|---|---|---|---|",
        f"| GTSAM LM | {gt_initial:.6f} | {gt_cost:.6f} | {rows[-1]['gtsam_iters']} | {gt_ms:.1f} | 1 |",
        f"| `segloc graph stereo-ba` | {seg0['initial_cost']:.6f} | {seg0['final_cost']:.6f} | {seg0['iterations']} | "
        f"{seg_ms:.1f} | **{speedup:.1f}×** (min {min(ratios):.1f}×) |",
        "",
        f"Targets: same final cost (1e-6 relative) — rel. diff {rel:+.1e}: {'met' if met else '**not met**'}; "
        f"≥ 4× GTSAM's speed — {speedup:.1f}×: {'met' if speedup >= 4 else '**not met**'}.",
    ]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        write_section(args.benchmarks, "stereo-ba", text)


if __name__ == "__main__":
    main()
