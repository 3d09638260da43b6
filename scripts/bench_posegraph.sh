#!/usr/bin/env bash
# Pose-graph benchmark: segloc against GTSAM on the public 3D datasets, side by side.
#
# Creates a virtual environment under target/bench-venv, installs gtsam from PyPI (it ships
# sphere2500.txt and its ground truth in its Data/ folder), builds segloc in release mode and
# runs scripts/bench_posegraph.py, which times GTSAM's Levenberg–Marquardt and
# `segloc graph optimize` on the same file in one run (one thread each, pinned to one core),
# checks robustness to wrong loop closures and incremental updates, and writes the section
# "## Pose graph (issue 3)" of BENCHMARKS.md.
#
# Usage: scripts/bench_posegraph.sh [--runs N] [--seeds N] [--no-write] [--datasets-section]
# (--datasets-section: only the public and generated datasets against GTSAM, printed as a
# short markdown section; nothing is written)
# Env: SEGLOC_BENCH_VENV (an existing virtual environment with gtsam), CARGO_TARGET_DIR.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
TARGET="${CARGO_TARGET_DIR:-$ROOT/target}"
VENV="${SEGLOC_BENCH_VENV:-$TARGET/bench-venv}"
GTSAM_VERSION="${GTSAM_VERSION:-4.3.0}"

if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
if ! "$VENV/bin/python" -c "import gtsam" 2>/dev/null; then
    "$VENV/bin/pip" install --quiet "gtsam==$GTSAM_VERSION"
fi
(cd "$ROOT" && CARGO_TARGET_DIR="$TARGET" cargo build --release --quiet --bin segloc)

export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 RAYON_NUM_THREADS=1
exec "$VENV/bin/python" "$ROOT/scripts/bench_posegraph.py" \
    --segloc "$TARGET/release/segloc" --benchmarks "$ROOT/BENCHMARKS.md" --workdir "$TARGET/bench-posegraph" "$@"
