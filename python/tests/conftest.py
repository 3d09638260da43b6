"""Shared fixtures: the real data (SEGLOC_DATA, default ../shared/data beside the repo) and
the segloc CLI (SEGLOC_BIN, default target/release/segloc). Under CI=true a test that
needs either fails when it is missing instead of skipping."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
PAPER_PAIRS = [(3, 5), (3, 7), (5, 7), (5, 12), (7, 12)]


def _missing(what: str):
    if os.environ.get("CI") == "true":
        pytest.fail(f"{what} is missing (CI=true: a test needing it must not skip)")
    pytest.skip(f"{what} is missing")


@pytest.fixture(scope="session")
def data_dir() -> Path:
    data = Path(os.environ.get("SEGLOC_DATA", REPO / ".." / "shared" / "data"))
    if not (data / "lunarloc" / "traverse_3.csv").is_file():
        _missing(f"the LunarLoc traverses under {data} (set SEGLOC_DATA)")
    return data


@pytest.fixture(scope="session")
def segloc_bin() -> str:
    candidates = [os.environ.get("SEGLOC_BIN")]
    target = os.environ.get("CARGO_TARGET_DIR", str(REPO / "target"))
    candidates.append(str(Path(target) / "release" / "segloc"))
    candidates.append(shutil.which("segloc"))
    for c in candidates:
        if c and Path(c).is_file() and os.access(c, os.X_OK):
            return c
    _missing("the segloc binary (cargo build --release, or set SEGLOC_BIN)")


def traverse(data_dir: Path, n: int) -> Path:
    return data_dir / "lunarloc" / f"traverse_{n}.csv"


def yaw_transform(rng: np.random.Generator) -> np.ndarray:
    """A random rigid transform keeping z up: any yaw, +-20 m in x and y, +-1 m in z (as
    `segloc eval lunarloc --dof 4` draws them)."""
    yaw = rng.uniform(-np.pi, np.pi)
    c, s = np.cos(yaw), np.sin(yaw)
    t = np.eye(4)
    t[:2, :2] = [[c, -s], [s, c]]
    t[:3, 3] = [rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-1, 1)]
    return t


def inverse(t: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = t[:3, :3].T
    out[:3, 3] = -t[:3, :3].T @ t[:3, 3]
    return out
