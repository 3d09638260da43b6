#!/usr/bin/env python3
"""Pose-graph benchmark of issue 3 (run through scripts/bench_posegraph.sh).

GTSAM and segloc solve sphere2500 (TORO 3D, 2,500 poses, 4,949 edges, no vertices) with pose 0
fixed and the chained-odometry initial estimate. Both run on one thread pinned to the same
core; runs alternate so that both see the same machine load. The TORO information entries are
in (x y z roll pitch yaw) order and are reordered to GTSAM's (rotation, translation) tangent
here (GTSAM's own readG2o keeps the file order, which gives a different problem: cost 1133).
"""

import argparse
import datetime
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

SECTION = "## Pose graph (issue 3)"

# Public 3D pose graphs shipped in the gtsam wheel's Data/ that both solvers read the same way.
# Left out: sphere_smallnoise.graph (its EDGE3 lines carry no information matrix: segloc
# refuses it naming the line, GTSAM's reader keeps one factor with a garbage noise model),
# pose3example-offdiagonal-rewritten.txt (the same graph as pose3example-offdiagonal.txt),
# known_landmark_localization_*.g2o and example_with_vertices.g2o (landmark edges
# EDGE_SE3_TRACKXYZ, which segloc skips and GTSAM reads: different problems).
PUBLIC = ["sphere2500.txt", "pose3example.txt", "pose3example-grid.txt", "pose3example-offdiagonal.txt",
          "pose3Localizationexample.txt", "simpleGraph10gradIter.txt", "toyExample.g2o", "Klaus3.g2o"]
# Harder graphs from scripts/gen_posegraph.py with bignoise-like noise (σ_R = 0.1 rad,
# σ_t = 0.1 m per edge): (label, shape, size, seed).
GENERATED = [("sphere, bignoise-like", "sphere", 50, 1), ("torus, bignoise-like", "torus", 40, 1),
             ("grid3D, bignoise-like", "grid", 8, 1)]


def data_file(name):
    path = os.path.join(os.path.dirname(gtsam.__file__), "Data", name)
    if not os.path.exists(path):
        sys.exit(f"{path} not found in the gtsam package")
    return path


def read_toro(path):
    """Edges (i, j, Pose3, information in GTSAM order) of a TORO 3D file."""
    edges = []
    for line in open(path):
        t = line.split()
        if not t or t[0] != "EDGE3":
            continue
        i, j = int(t[1]), int(t[2])
        x, y, z, roll, pitch, yaw = map(float, t[3:9])
        upper = list(map(float, t[9:30]))
        info = np.zeros((6, 6))
        k = 0
        for a in range(6):
            for b in range(a, 6):
                info[a, b] = info[b, a] = upper[k]
                k += 1
        perm = [3, 4, 5, 0, 1, 2]  # (x y z roll pitch yaw) -> (rotation, translation)
        info = info[np.ix_(perm, perm)]
        pose = gtsam.Pose3(gtsam.Rot3.RzRyRx(roll, pitch, yaw), gtsam.Point3(x, y, z))
        edges.append((i, j, pose, info))
    return edges


def build_problem(edges, anchor=None):
    """Between factors in edge order, the chained-odometry initial estimate, and pose 0 held by
    `anchor` (the last factor; default an exact equality)."""
    graph = gtsam.NonlinearFactorGraph()
    for i, j, pose, info in edges:
        graph.add(gtsam.BetweenFactorPose3(i, j, pose, gtsam.noiseModel.Gaussian.Information(info)))
    initial = gtsam.Values()
    initial.insert(0, gtsam.Pose3())
    for i, j, pose, _ in edges:
        if j == i + 1 and not initial.exists(j):
            initial.insert(j, initial.atPose3(i).compose(pose))
    graph.add(anchor if anchor is not None else gtsam.NonlinearEqualityPose3(0, gtsam.Pose3()))
    return graph, initial


def run_gtsam(graph, initial):
    params = gtsam.LevenbergMarquardtParams()
    t0 = time.perf_counter()
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, params)
    result = optimizer.optimize()
    seconds = time.perf_counter() - t0
    return graph.error(result), optimizer.iterations(), seconds * 1e3


def is_toro(path):
    for line in open(path):
        t = line.split()
        if t:
            return t[0] in ("EDGE3", "VERTEX3")
    return False


def gtsam_problem(path):
    """The graph as GTSAM solves it, from the file's vertices (chained odometry for a TORO
    file without them), the first pose held by an exact equality (as segloc fixes it)."""
    if is_toro(path):
        return build_problem(read_toro(path))
    graph, initial = gtsam.readG2o(path, True)
    first = min(initial.keys())
    graph.add(gtsam.NonlinearEqualityPose3(first, initial.atPose3(first)))
    return graph, initial


def zero_to_rounding(cost, initial_cost):
    return cost <= max(1e-10 * initial_cost, 1e-25)


def dataset_rows(args, seg):
    """GTSAM LM against segloc (default, and from GTSAM's start) on every dataset."""
    files = [(name, data_file(name)) for name in PUBLIC]
    gen = os.path.join(os.path.dirname(os.path.abspath(__file__)), "gen_posegraph.py")
    for label, shape, size, seed in GENERATED:
        out = os.path.join(args.workdir, f"{shape}{size}_bignoise.g2o")
        subprocess.run([sys.executable, gen, shape, "-o", out, "--size", str(size), "--seed", str(seed)],
                       check=True, capture_output=True)
        files.append((f"{label} (`gen_posegraph.py {shape} --size {size}`)", out))
    rows = []
    for name, path in files:
        graph, initial = gtsam_problem(path)
        same_start = "odometry" if is_toro(path) and "VERTEX3" not in open(path).read(4096) else "file"
        runs = args.runs if graph.size() < 2000 else max(3, args.runs // 2)
        g_runs, s_runs, f_runs = [], [], []
        for _ in range(runs):
            g_runs.append(run_gtsam(graph, initial))
            s_runs.append(seg("optimize", path, "--repeat", "3"))
            f_runs.append(seg("optimize", path, "--init", same_start, "--repeat", "3"))
        g_cost, g_iters = g_runs[0][0], g_runs[0][1]
        row = {
            "name": name, "poses": s_runs[0]["poses"], "edges": s_runs[0]["factors"],
            "gtsam_initial": graph.error(initial), "gtsam_cost": g_cost, "gtsam_iters": g_iters,
            "gtsam_ms": statistics.median(x[2] for x in g_runs), "same_start": same_start,
            "repaired": s_runs[0]["repaired_information"]["count"],
        }
        for key, rs in (("seg", s_runs), ("same", f_runs)):
            row[key + "_cost"] = rs[0]["final_cost"]
            row[key + "_iters"] = rs[0]["iterations"]
            row[key + "_ms"] = statistics.median(r["time_median_ms"] for r in rs)
            row[key + "_speedup"] = statistics.median(g[2] / r["time_median_ms"] for g, r in zip(g_runs, rs))
            zero = zero_to_rounding(max(row[key + "_cost"], g_cost), row["gtsam_initial"])
            row[key + "_rel"] = None if zero else (row[key + "_cost"] - g_cost) / g_cost
            row[key + "_ok"] = zero or row[key + "_cost"] <= g_cost * (1 + 1e-6)
        print(f"{name}: gtsam {g_cost:.9g} {row['gtsam_ms']:.2f} ms, segloc {row['seg_cost']:.9g} "
              f"{row['seg_ms']:.2f} ms ({row['seg_speedup']:.1f}x)", file=sys.stderr)
        rows.append(row)
    return rows


def dataset_lines(rows):
    def rel(r, key):
        return "both 0 (rounding)" if r[key + "_rel"] is None else f"{r[key + '_rel']:+.1e}"

    lines = [
        "### Public 3D datasets and harder generated ones: final cost and time against GTSAM's LM",
        "",
        "Every 3D pose graph of the gtsam wheel's `Data/` that both solvers read as the same problem "
        "(left out: `sphere_smallnoise.graph`, whose `EDGE3` lines have no information matrix — segloc "
        "refuses it naming line 2201, GTSAM's reader keeps one factor; the landmark files with "
        "`EDGE_SE3_TRACKXYZ`, which segloc skips; a rewritten duplicate), and three harder graphs "
        "generated by `scripts/gen_posegraph.py` with the noise of the public *bignoise* variants "
        "(σ_R = 0.1 rad, σ_t = 0.1 m per edge; vertices from the chained noisy odometry, as in the "
        "public files). GTSAM: `LevenbergMarquardtOptimizer` with default parameters from the file's "
        "vertices (sphere2500: chained odometry), first pose held by an equality. segloc: `graph "
        "optimize` by default (chordal start), and from GTSAM's start (`--init file`, sphere2500 "
        "`--init odometry`). Time: median over runs of the solve alone (GTSAM warm in one Python "
        "process; segloc the median of 3 solves in one process, analysis included). Speed-up: median "
        "over runs of GTSAM time / segloc time in the same run. Rel. diff = (segloc − GTSAM) / GTSAM, "
        "negative when segloc ends lower; costs below 1e-10 of the initial cost count as 0. No file "
        "here has an information matrix that is not positive definite (repaired: 0 everywhere).",
        "",
        "| dataset | poses | edges | GTSAM LM cost (iter.) | segloc default cost (iter.) | rel. diff | "
        "segloc from GTSAM's start cost (iter.) | rel. diff | GTSAM (ms) | segloc default (ms) | "
        "segloc same start (ms) | speed-up default | speed-up same start |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['name']} | {r['poses']} | {r['edges']} | {r['gtsam_cost']:.9g} ({r['gtsam_iters']}) | "
            f"{r['seg_cost']:.9g} ({r['seg_iters']}) | {rel(r, 'seg')} | {r['same_cost']:.9g} "
            f"({r['same_iters']}) | {rel(r, 'same')} | {r['gtsam_ms']:.2f} | {r['seg_ms']:.2f} | "
            f"{r['same_ms']:.2f} | **{r['seg_speedup']:.1f}×** | {r['same_speedup']:.1f}× |")
    ok = sum(r["seg_ok"] and r["same_ok"] for r in rows)
    fast = [r for r in rows if r["seg_speedup"] >= 4]
    slow = [r for r in rows if r["seg_speedup"] < 4]

    def names(rs):
        return ", ".join(f"{r['name'].split(' (')[0]} {r['seg_speedup']:.1f}×" for r in rs)

    why = []
    if [r for r in slow if r["poses"] < 100]:
        why.append(names([r for r in slow if r["poses"] < 100]) + ": a graph of a few dozen poses, "
                   "where both solves take about a millisecond and segloc's fixed costs per solve "
                   "(symbolic analysis, chordal start, allocations) weigh most")
    if [r for r in slow if r["poses"] >= 100]:
        why.append(names([r for r in slow if r["poses"] >= 100]) + ": times on a shared machine "
                   "(load above); the same solve measured in alternating cold runs is in the "
                   "sphere2500 table above")
    lines += [
        "",
        f"Targets: segloc's cost the same as GTSAM's or lower (within 1e-6 relative) — {ok} of "
        f"{len(rows)} datasets, both starts" + (" (met)" if ok == len(rows) else " (**not met**)") +
        f"; ≥ 4× faster than GTSAM by default — {len(fast)} of {len(rows)} datasets"
        + (" (met)." if not slow else " (**not met** on " + "; ".join(why) + ")."),
        "",
    ]
    return lines


def dataset_section(rows, args, load):
    """The datasets against GTSAM as a short markdown section (at most 25 lines)."""
    def rel(r):
        return "0 (both at rounding)" if r["seg_rel"] is None else f"{r['seg_rel']:+.1e}"

    lines = [
        "### Pose graph: public 3D datasets against GTSAM's LM (issue 25 §2)",
        "",
        f"`SEGLOC_BENCH_VENV=/work/venv-g2o scripts/bench_posegraph.sh --datasets-section --runs {args.runs}` — "
        f"{now_date()}, commit {git_revision(os.path.dirname(os.path.abspath(args.benchmarks)))}, "
        f"AMD EPYC, 2 cores (shared, load {load:.1f} at the start), gtsam {gtsam_version()}. One thread "
        f"each, pinned to CPU {args.cpu}, runs alternating; GTSAM LM from the file's vertices, segloc "
        "`graph optimize` by default (chordal start), median of 3 solves per process; times exclude "
        "reading; speed-up = median over runs of GTSAM/segloc time in the same run "
        "(graphs over 2,000 factors: half the runs).",
        "",
        "| dataset | poses / edges | GTSAM LM cost | segloc cost | rel. diff | GTSAM (ms) | segloc (ms) "
        "| speed-up | same start |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['name'].split(' (')[0]} | {r['poses']} / {r['edges']} | {r['gtsam_cost']:.9g} | "
            f"{r['seg_cost']:.9g} | {rel(r)} | {r['gtsam_ms']:.2f} | {r['seg_ms']:.3f} | "
            f"**{r['seg_speedup']:.1f}×** | {r['same_speedup']:.1f}× |")
    ok = sum(r["seg_ok"] and r["same_ok"] for r in rows)
    fast = sum(r["seg_speedup"] >= 4 for r in rows)
    lines += [
        "",
        f"Cost the same or lower (1e-6 relative), both starts: {ok} of {len(rows)}; ≥ 4× faster by "
        f"default: {fast} of {len(rows)}" + (" (met)." if fast == len(rows) else " (**not met**)."),
    ]
    return lines


def run_gtsam_chordal(graph, initial):
    """GTSAM's own chordal initialisation (InitializePose3) followed by LM, timed together."""
    pose_graph = gtsam.NonlinearFactorGraph()
    for k in range(graph.size()):
        f = graph.at(k)
        if isinstance(f, gtsam.BetweenFactorPose3):
            pose_graph.add(f)
    pose_graph.add(gtsam.PriorFactorPose3(0, gtsam.Pose3(), gtsam.noiseModel.Unit.Create(6)))
    t0 = time.perf_counter()
    start = gtsam.InitializePose3.initialize(pose_graph)
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, start, gtsam.LevenbergMarquardtParams())
    result = optimizer.optimize()
    seconds = time.perf_counter() - t0
    return graph.error(result), optimizer.iterations(), seconds * 1e3


def run_gtsam_gnc(corrupted, out_path):
    """GTSAM's graduated non-convexity (GncLMOptimizer, truncated least squares) on a corrupted
    TORO file, odometry edges given as known inliers (segloc's kernel applies to loop closures
    only), from the chained odometry; writes the poses as g2o vertices. Returns (ms, rejected)."""
    edges = read_toro(corrupted)
    # GNC weighs noise-model factors only: pose 0 is held by a tight prior, not an equality
    anchor = gtsam.PriorFactorPose3(0, gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-6))
    graph, initial = build_problem(edges, anchor)
    known = [k for k, (i, j, _, _) in enumerate(edges) if j == i + 1] + [len(edges)]
    params = gtsam.GncLMParams()
    params.setKnownInliers(known)
    t0 = time.perf_counter()
    optimizer = gtsam.GncLMOptimizer(graph, initial, params)
    result = optimizer.optimize()
    ms = (time.perf_counter() - t0) * 1e3
    with open(out_path, "w") as f:
        for i in range(initial.size()):
            p = result.atPose3(i)
            t, q = p.translation(), p.rotation().toQuaternion()
            f.write(f"VERTEX_SE3:QUAT {i} {t[0]} {t[1]} {t[2]} {q.x()} {q.y()} {q.z()} {q.w()}\n")
    return ms, int(sum(1 for w in optimizer.getWeights() if w < 0.5))


def segloc(binary, *args):
    out = subprocess.run([binary, "graph", *args], check=True, capture_output=True, text=True)
    return out.stdout


def segloc_json(binary, *args):
    return json.loads(segloc(binary, *args, "--json"))


def ate(binary, estimate, truth):
    return json.loads(segloc(binary, "ate", estimate, truth, "--align", "--json"))


def drop_replaced(original, corrupted, out):
    """Writes `corrupted` without the edges that differ from `original` (the oracle)."""
    kept, dropped = [], 0
    for a, b in zip(open(original), open(corrupted)):
        ta, tb = a.split(), b.split()
        if not tb:
            continue
        if all(abs(float(x) - float(y)) < 1e-9 for x, y in zip(ta[3:9], tb[3:9])):
            kept.append(b)
        else:
            dropped += 1
    open(out, "w").writelines(kept)
    return dropped


def gtsam_version():
    try:
        from importlib.metadata import version
        return version("gtsam")
    except Exception:  # noqa: BLE001 - only for the report
        return getattr(gtsam, "__version__", "?")


def machine():
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def now_date():
    """The output of `date` (the report's date, with time and zone)."""
    try:
        return subprocess.run(["date"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return datetime.datetime.now(datetime.timezone.utc).isoformat()


def git_revision(root):
    try:
        rev = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", root, "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return rev + ("+changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--segloc", required=True)
    ap.add_argument("--benchmarks", required=True)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--cpu", type=int, default=0)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--datasets-only", action="store_true",
                    help="print the datasets table only; write nothing")
    ap.add_argument("--datasets-section", action="store_true",
                    help="run only the public/generated datasets against GTSAM and print a short "
                         "markdown section (at most 25 lines); write nothing")
    args = ap.parse_args()
    os.makedirs(args.workdir, exist_ok=True)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {args.cpu})  # GTSAM runs in this process: one core
    pin = ["taskset", "-c", str(args.cpu)] if subprocess.run(
        ["which", "taskset"], capture_output=True).returncode == 0 else []
    binary = args.segloc
    sphere = data_file("sphere2500.txt")
    truth = data_file("sphere2500_groundtruth.txt")

    def seg(*a):
        return json.loads(subprocess.run(pin + [binary, "graph", *a, "--json"], check=True,
                                         capture_output=True, text=True).stdout)

    if args.datasets_section:
        load = os.getloadavg()[0]
        print("\n".join(dataset_section(dataset_rows(args, seg), args, load)))
        return

    # --- public datasets and generated bignoise-like graphs -----------------------------------
    data_rows = dataset_rows(args, seg)
    if args.datasets_only:
        print("\n".join(dataset_lines(data_rows)))
        return

    # --- robustness: 10% of the loop closures replaced by random relative poses ----------------
    clean_out = os.path.join(args.workdir, "clean_out.txt")
    seg("optimize", sphere, "-o", clean_out)
    clean_ate = ate(binary, clean_out, truth)
    robust_rows = []
    for seed in range(1, args.seeds + 1):
        corrupted = os.path.join(args.workdir, f"corrupt_{seed}.txt")
        segloc(binary, "corrupt", sphere, "-o", corrupted, "--fraction", "0.1", "--seed", str(seed))
        oracle = os.path.join(args.workdir, f"oracle_{seed}.txt")
        dropped = drop_replaced(sphere, corrupted, oracle)
        row = {"seed": seed, "replaced": dropped}
        oracle_out = os.path.join(args.workdir, f"oracle_{seed}_out.txt")
        seg("optimize", oracle, "-o", oracle_out)
        row["oracle"] = ate(binary, oracle_out, truth)
        for kernel in ("none", "huber", "cauchy", "gnc"):
            out = os.path.join(args.workdir, f"corrupt_{seed}_{kernel}.txt")
            rep = seg("optimize", corrupted, "--robust", kernel, "-o", out)
            row[kernel] = ate(binary, out, truth)
            row[kernel + "_ms"] = rep["time_ms"]
        gtsam_out = os.path.join(args.workdir, f"corrupt_{seed}_gtsam_gnc.g2o")
        row["gtsam_gnc_ms"], row["gtsam_rejected"] = run_gtsam_gnc(corrupted, gtsam_out)
        row["gtsam_gnc"] = ate(binary, gtsam_out, truth)
        robust_rows.append(row)
        print(f"seed {seed}: gnc ATE {row['gnc']['position_rmse_m']:.4f} m, oracle "
              f"{row['oracle']['position_rmse_m']:.4f} m, clean {clean_ate['position_rmse_m']:.4f} m",
              file=sys.stderr)

    # --- incremental ---------------------------------------------------------------------------
    inc = seg("bench-incremental")
    # Stress: 500 consecutive loop-closure appends make a 590-pose stretch in which every
    # pose closes a loop, longer than the window may grow (500 poses).
    inc_stress = seg("bench-incremental", "--appends", "500")

    # --- report --------------------------------------------------------------------------------
    c = clean_ate["position_rmse_m"]
    lines = [
        SECTION,
        "",
        f"Command: `scripts/bench_posegraph.sh --runs {args.runs}` — {now_date()}, "
        f"commit {git_revision(os.path.dirname(os.path.abspath(args.benchmarks)))}, machine `{machine()}` "
        f"({os.cpu_count()} cores, shared; load average {os.getloadavg()[0]:.1f} at the start), gtsam {gtsam_version()} from PyPI, "
        f"Python {platform.python_version()}. One thread each (RAYON_NUM_THREADS=1 for segloc; GTSAM "
        "wheel from PyPI is built without TBB: single-threaded), pinned to CPU "
        f"{args.cpu}; the runs "
        "alternate so both solvers see the same load; times exclude file reading; the first ratio is "
        "the median over runs of segloc/GTSAM time in the same run, the second the ratio of the best "
        "times.",
        "",
        *dataset_lines(data_rows),
        "### Wrong loop closures (10% of the 2,450 loop closures replaced by random relative poses)",
        "",
        "`segloc graph corrupt --fraction 0.1 --seed N` replaces 245 loop closures by a uniformly random "
        "rotation and a translation uniform in ±10 m; the robust kernel applies to loop closures only. "
        "Error = position RMSE (m) against `sphere2500_groundtruth.txt` after a rigid alignment. "
        f"Clean solution: {c:.4f} m. The *oracle* solves the corrupted file with the wrong closures "
        "removed, i.e. the best any robust method can do: the 245 true closures that were replaced are "
        "lost information.",
        "",
        "| seed | none | Huber (k=3) | Cauchy (c=3) | GNC → TLS (c=4) | oracle | GNC vs clean | GNC vs oracle | GNC time (ms) | GTSAM GNC (TLS) | GTSAM GNC vs clean | GTSAM GNC time (ms) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in robust_rows:
        g = row["gnc"]["position_rmse_m"]
        o = row["oracle"]["position_rmse_m"]
        lines.append(
            f"| {row['seed']} | {row['none']['position_rmse_m']:.4f} | {row['huber']['position_rmse_m']:.4f} | "
            f"{row['cauchy']['position_rmse_m']:.4f} | {g:.4f} | {o:.4f} | {100 * (g / c - 1):+.1f}% | "
            f"{100 * (g / o - 1):+.2f}% | {row['gnc_ms']:.0f} | {row['gtsam_gnc']['position_rmse_m']:.4f} | "
            f"{100 * (row['gtsam_gnc']['position_rmse_m'] / c - 1):+.1f}% | {row['gtsam_gnc_ms']:.0f} |")
    worst = max(r["gnc"]["position_rmse_m"] / c - 1 for r in robust_rows)
    worst_oracle = max(abs(r["gnc"]["position_rmse_m"] / r["oracle"]["position_rmse_m"] - 1) for r in robust_rows)
    lines += [
        "",
        f"Target (within 5% of the clean solution): {sum(r['gnc']['position_rmse_m'] / c - 1 <= 0.05 for r in robust_rows)} "
        f"of {len(robust_rows)} seeds within 5%, median "
        f"{100 * statistics.median(r['gnc']['position_rmse_m'] / c - 1 for r in robust_rows):+.1f}%, worst seed {100 * worst:+.1f}% — "
        + ("met" if worst <= 0.05 else "**not met on every seed**")
        + f"; GNC matches the oracle within 0.5% on {sum(abs(r['gnc']['position_rmse_m'] / r['oracle']['position_rmse_m'] - 1) <= 5e-3 for r in robust_rows)} "
        f"of {len(robust_rows)} seeds (worst {100 * worst_oracle:.2f}%; differences of a few hundredths of a percent are "
        "the two solves' convergence tolerance). Where it does, the gap to the clean solution is the "
        "information of the 245 replaced true closures, which no robust method can recover: the oracle "
        f"itself is within 5% of the clean solution on {sum(r['oracle']['position_rmse_m'] / c - 1 <= 0.05 for r in robust_rows)} "
        f"of {len(robust_rows)} seeds (median {100 * statistics.median(r['oracle']['position_rmse_m'] / c - 1 for r in robust_rows):+.1f}%; "
        "losing a tenth of the loop closures' information raises the error by about √(1/0.9) − 1 ≈ 5.4% "
        "on average), so the target as stated is out of reach for any estimator on a good share of seeds. "
        "The peer agrees: GTSAM's own GNC (GncLMOptimizer, TLS, odometry as known inliers, same files) "
        f"rejects {statistics.median(r['gtsam_rejected'] for r in robust_rows):.0f} closures (median) and is within 5% of the clean "
        f"solution on {sum(r['gtsam_gnc']['position_rmse_m'] / c - 1 <= 0.05 for r in robust_rows)} of {len(robust_rows)} seeds "
        f"(median {100 * statistics.median(r['gtsam_gnc']['position_rmse_m'] / c - 1 for r in robust_rows):+.1f}%), "
        f"in {statistics.median(r['gtsam_gnc_ms'] / r['gnc_ms'] for r in robust_rows):.0f}× segloc's GNC time (median of per-seed ratios).",
        "",
        "### Incremental (synthetic 5,000-pose graph, 200 loop closures; `segloc graph bench-incremental`)",
        "",
        "| update | median (ms) | p90 (ms) | max (ms) |",
        "|---|---|---|---|",
    ]
    for key, label in (("odometry_append_ms", "append 1 pose + 1 odometry factor (consecutive)"),
                       ("loop_closure_append_ms", "append 1 pose + odometry + 1 loop closure (consecutive, batches included)"),
                       ("loop_closure_incremental_ms", "… of which incremental updates (window exact, settled part on the last linearisation)"),
                       ("loop_closure_relinearized_ms", "… of which model rebuilds at the incremental estimate"),
                       ("loop_closure_batch_ms", "… of which batch re-optimisations"),
                       ("odometry_append_full_ms", "reference: append + forced full warm-started batch re-optimisation")):
        s = inc.get(key)
        if not s or s["median"] is None:
            continue
        lines.append(f"| {label} | {s['median']:.3f} | {s['p90']:.3f} | {s['max']:.3f} |")
    gap = inc["loop_closure_cost_gap"]
    diff = inc["loop_closure_max_position_diff_m"]
    n_lc = inc["loop_closure_incremental"] + inc.get("loop_closure_relinearized", 0) + inc["loop_closure_batch"]
    lc = inc["loop_closure_append_ms"]
    lines += [
        "",
        f"Batch solve of the base graph: {inc['batch_ms']:.1f} ms, {inc['batch_iterations']} iterations. "
        f"{100 * inc['odometry_append_skipped']:.0f}% of odometry appends were recognised as leaving the "
        "optimum unchanged (zero gradient from the new factor) and needed no solve. Loop-closure appends: "
        f"{inc['loop_closure_incremental']} of {n_lc} were incremental updates (the factors among "
        "settled variables kept to second order at the last linearisation point, as in iSAM; the factors "
        "of the last 100 free poses, the window, evaluated exactly: Gauss–Newton on a sparse problem over "
        "the window and the settled variables its factors touch, whose marginal comes from forward solves "
        "along their elimination paths, then one backward solve with the settled part's factor moves every "
        "settled pose), "
        f"{inc.get('loop_closure_relinearized', 0)} built the model again at the incremental estimate "
        "(a settled variable had moved more than 0.1 from its linearisation point, or the window, growing "
        "with every appended pose, had passed 500 poses or its boundary 40 variables), and "
        f"{inc['loop_closure_batch']} were batch re-optimisations (no model could be built, or a rebuilt "
        "model's update did not lower the cost). Accuracy against a "
        "full batch optimum of the same graph after every loop-closure append: relative cost gap median "
        f"{gap['median']:.1e}, max {gap['max']:.1e}; largest position difference median "
        f"{1e3 * diff['median']:.2f} mm, max {1e3 * diff['max']:.2f} mm. "
        "Target ≤ 5 ms for one pose + one factor: odometry append "
        + ("met" if inc["odometry_append_ms"]["p90"] <= 5 else "**not met**")
        + f"; loop-closure append median {lc['median']:.2f} ms, p90 {lc['p90']:.2f} ms "
        + ("(met)" if lc["p90"] <= 5 else ("(median met, p90 **not met**)" if lc["median"] <= 5 else "(**not met**)"))
        + f", max {lc['max']:.1f} ms.",
        "",
        "Stress (`segloc graph bench-incremental --appends 500`): 500 odometry appends, then 500 "
        "consecutive loop-closure appends, so that the closures form a stretch of about 590 poses "
        "in which every pose closes a loop 40–90 poses back — longer than the window may grow. "
        f"Loop-closure append median {inc_stress['loop_closure_append_ms']['median']:.2f} ms, "
        f"p90 {inc_stress['loop_closure_append_ms']['p90']:.2f} ms, max "
        f"{inc_stress['loop_closure_append_ms']['max']:.1f} ms; "
        f"{inc_stress['loop_closure_incremental']} incremental, "
        f"{inc_stress.get('loop_closure_relinearized', 0)} model rebuilds (median "
        f"{(inc_stress['loop_closure_relinearized_ms']['median'] or 0):.0f} ms), "
        f"{inc_stress['loop_closure_batch']} batches; cost gap max "
        f"{inc_stress['loop_closure_cost_gap']['max']:.1e}. Once the window is full inside such a "
        "stretch, any split leaves closures across it and the settled poses next to it keep moving "
        "past the relinearisation threshold, so the model is rebuilt every few updates; updating "
        "only the affected part of the factor (an iSAM2 Bayes tree) would avoid that and is not built.",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if args.no_write:
        return
    # only the block between this section's own markers is replaced
    write_section(args.benchmarks, "posegraph", text)


if __name__ == "__main__":
    main()
