"""Relocalize the LunarLoc paper pairs from Python, under one fixed rigid transform.

Each pair's query traverse is fused (as `segloc map build` does), moved into its own
frame and relocalized against the prior traverse: the transform found is compared with
the one applied. With --repeat N each call is timed N times after two warm-up calls (the
Python side of the bindings' overhead figure; `cargo run --release --example
relocalize_pairs_timing` makes the same calls in Rust).

    python examples/relocalize_pairs.py [--data ../shared/data] [--repeat 20] [--json]
"""

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

import segloc

PAPER_PAIRS = [(3, 5), (3, 7), (5, 7), (5, 12), (7, 12)]
# query_from_world: a yaw from the 3-4-5 triangle (exact in binary) and a translation;
# the same matrix as examples/relocalize_pairs_timing.rs
QUERY_FROM_WORLD = np.array(
    [[0.6, -0.8, 0.0, 3.0], [0.8, 0.6, 0.0, -2.0], [0.0, 0.0, 1.0, 0.5], [0.0, 0.0, 0.0, 1.0]]
)


def main() -> None:
    default_data = os.environ.get("SEGLOC_DATA", str(Path(__file__).resolve().parents[2] / ".." / "shared" / "data"))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=default_data, help="folder holding lunarloc/")
    parser.add_argument("--repeat", type=int, default=1, help="timed calls per pair")
    parser.add_argument("--json", action="store_true", help="one JSON line per pair")
    args = parser.parse_args()
    traverse = lambda n: Path(args.data) / "lunarloc" / f"traverse_{n}.csv"
    for a, b in PAPER_PAIRS:
        relocalizer = segloc.Relocalizer(segloc.read_traverse(traverse(a)))
        query = segloc.read_traverse(traverse(b)).transformed(QUERY_FROM_WORLD, "query")
        times_ms = []
        for k in range(args.repeat + 2):
            t = time.perf_counter()
            result = relocalizer.relocalize(query)
            if k >= 2 or args.repeat == 1 and k == 0:
                times_ms.append((time.perf_counter() - t) * 1e3)
            if args.repeat == 1:
                break
        median_ms = float(np.median(times_ms))
        if not result.accepted:
            line = {"pair": [a, b], "accepted": False, "refusal": result.refusal, "median_ms": median_ms}
        else:
            # prior_from_query should be world_from_query = QUERY_FROM_WORLD^-1
            err = QUERY_FROM_WORLD @ result.prior_from_query
            angle = np.degrees(np.arccos(np.clip((np.trace(err[:3, :3]) - 1) / 2, -1, 1)))
            line = {
                "pair": [a, b], "accepted": True, "inliers": int(len(result.inliers)),
                "rmse_cm": result.rmse_m * 100, "error_cm": float(np.linalg.norm(err[:3, 3]) * 100),
                "error_deg": float(angle), "median_ms": median_ms,
            }
        if args.json:
            print(json.dumps(line))
        elif line["accepted"]:
            print(f"{a:2} <- {b:2}: {line['inliers']:3} inliers, rmse {line['rmse_cm']:.2f} cm, "
                  f"error {line['error_cm']:.2f} cm / {line['error_deg']:.3f} deg, {median_ms:.2f} ms")
        else:
            print(f"{a:2} <- {b:2}: refused ({line['refusal']}), {median_ms:.2f} ms")


if __name__ == "__main__":
    main()
