#!/usr/bin/env bash
# Stereo bundle adjustment of issue 27: `segloc graph stereo-ba` against GTSAM's
# Levenberg–Marquardt on GTSAM's stereo VO example (VO_*_large.txt in the gtsam wheel's Data/),
# one thread each, side by side; writes the section "## Stereo bundle adjustment vs GTSAM" of
# BENCHMARKS.md (between its markers).
#
# Usage: scripts/bench_stereo_ba.sh [--runs N] [--no-write]
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
exec "$VENV/bin/python" "$ROOT/scripts/bench_stereo_ba.py" \
    --segloc "$TARGET/release/segloc" --benchmarks "$ROOT/BENCHMARKS.md" "$@"
