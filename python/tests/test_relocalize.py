"""The paper pairs relocalized from Python against the real traverses under random
transforms: the same answers as `segloc relocalize --json`, bit for bit."""

import json
import subprocess

import numpy as np
import pytest

import segloc
from conftest import PAPER_PAIRS, inverse, traverse, yaw_transform

TRIALS = 2


@pytest.mark.parametrize("pair", PAPER_PAIRS, ids=lambda p: f"{p[0]}-{p[1]}")
def test_paper_pair_matches_the_cli_bit_for_bit(pair, data_dir, segloc_bin, tmp_path):
    a, b = pair
    prior = segloc.read_traverse(traverse(data_dir, a))
    query_world = segloc.read_traverse(traverse(data_dir, b))
    relocalizer = segloc.Relocalizer(prior)
    rng = np.random.default_rng(1000 * a + b)
    for trial in range(TRIALS):
        truth = yaw_transform(rng)  # prior_from_query
        query = query_world.transformed(inverse(truth), "query")
        path = tmp_path / f"query_{trial}.map.json"
        segloc.write_map(query, path)
        result = relocalizer.relocalize(query)
        cli = subprocess.run(
            [segloc_bin, "relocalize", "--prior", str(traverse(data_dir, a)), "--query", str(path), "--json"],
            capture_output=True, text=True,
        )
        assert cli.returncode in (0, 1), cli.stderr
        report = json.loads(cli.stdout)
        assert result.accepted == (report["status"] == "ok")
        assert result.accepted, f"pair {pair} trial {trial}: {result.refusal}"
        # bit for bit: JSON carries every f64 in shortest round-trip form
        assert np.array_equal(result.prior_from_query, np.array(report["prior_from_query"]))
        assert np.array_equal(result.information, np.array(report["information"]))
        assert result.inliers.tolist() == report["inlier_pairs"]
        assert result.rmse_m == report["rmse_m"]
        assert result.dof == report["dof"] == 4
        # and right: within a few cm of the applied transform
        err = np.linalg.inv(truth) @ result.prior_from_query
        assert np.linalg.norm(err[:3, 3]) < 0.10
        assert result.information.shape == (6, 6)
        assert np.allclose(result.information, result.information.T)


def test_refusal_is_a_reason_not_an_error(data_dir):
    prior = segloc.read_traverse(traverse(data_dir, 3))
    rng = np.random.default_rng(5)
    # a random field of boulders shares no geometry with the traverse
    points = np.column_stack([rng.uniform(-10, 10, 40), rng.uniform(-10, 10, 40), rng.uniform(-0.1, 0.1, 40)])
    result = segloc.Relocalizer(prior).relocalize(segloc.ObjectMap.from_points(points))
    assert not result.accepted
    assert result.prior_from_query is None
    assert isinstance(result.refusal, str) and result.refusal
    assert result.to_dict()["refusal"]["kind"]
    assert np.all(result.information == 0)


def test_from_points_and_config(data_dir):
    world = segloc.read_traverse(traverse(data_dir, 5))
    prior = segloc.read_traverse(traverse(data_dir, 3))
    truth = yaw_transform(np.random.default_rng(3))
    moved = world.transformed(inverse(truth), "query")
    # bare points (no covariance, sizes unknown) relocalize too
    query = segloc.ObjectMap.from_points(moved.points, sizes=None, gravity_aligned=True)
    assert len(query) == len(world)
    assert np.array_equal(query.points, moved.points)
    assert np.all(np.isnan(query.sizes))
    config = segloc.RelocalizeConfig(dof=6, verification={"min_inliers": 8})
    assert config.dof == 6 and config.to_dict()["verification"]["min_inliers"] == 8
    assert segloc.RelocalizeConfig.from_toml(config.to_toml()).to_dict() == config.to_dict()
    result = segloc.Relocalizer(prior, config=config).relocalize(query)
    assert result.dof == 6
    assert result.accepted, result.refusal
    err = np.linalg.inv(truth) @ result.prior_from_query
    assert np.linalg.norm(err[:3, 3]) < 0.10
    assert set(result.timings_ms) >= {"associations_ms", "graph_ms", "clique_ms", "alignment_ms", "total_ms"}


def test_read_detections_and_fuse_as_read_traverse(data_dir):
    detections = segloc.read_detections(traverse(data_dir, 3))
    assert len(detections) > 100 and detections.points.shape == (len(detections), 3)
    fused = segloc.fuse_detections(detections)
    assert np.array_equal(fused.points, segloc.read_traverse(traverse(data_dir, 3)).points)
    coarser = segloc.fuse_detections(detections, cluster_radius_m=0.5)
    assert len(coarser) < len(fused)


def test_map_file_round_trip(data_dir, tmp_path):
    m = segloc.read_traverse(traverse(data_dir, 7))
    segloc.write_map(m, tmp_path / "m.json")
    back = segloc.read_map(tmp_path / "m.json")
    assert len(back) == len(m) and back.session == m.session and back.gravity_aligned
    for name in ("points", "covariances", "ids", "observations"):
        assert np.array_equal(getattr(back, name), getattr(m, name))
