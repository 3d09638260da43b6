"""Bad input raises segloc.SegLocError naming the file (and line); nothing panics."""

import numpy as np
import pytest

import segloc
from conftest import traverse


def test_bad_traverse_names_file_and_line(tmp_path):
    path = tmp_path / "traverse_99.csv"
    path.write_text(
        "frame,x,y,z,detections,boulders\n"
        '0,0.0,0.0,0.0,1,"[(1.0, 2.0, 3.0)]"\n'
        '20,0.0,0.0,0.0,1,"[(1.0, 2.0]"\n'
    )
    with pytest.raises(segloc.SegLocError, match=r"traverse_99\.csv:3"):
        segloc.read_traverse(path)
    with pytest.raises(segloc.SegLocError, match=r"traverse_99\.csv:3"):
        segloc.read_detections(path)


def test_bad_map_file_names_file(tmp_path):
    path = tmp_path / "broken.map.json"
    path.write_text('{"format": "segloc-map", "version": 99}\n')
    with pytest.raises(segloc.SegLocError, match="broken.map.json"):
        segloc.read_map(path)
    with pytest.raises(segloc.SegLocError, match="missing.json"):
        segloc.read_map(tmp_path / "missing.json")


def test_bad_pose_graph_names_file_and_line(tmp_path):
    path = tmp_path / "bad.g2o"
    path.write_text("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 oops\n")
    with pytest.raises(segloc.SegLocError, match=r"bad\.g2o:2"):
        segloc.optimize_pose_graph(path)
    with pytest.raises(segloc.SegLocError, match="solver configuration"):
        segloc.optimize_pose_graph(path, max_iterations="many")


def test_bad_arrays_and_configs():
    with pytest.raises(segloc.SegLocError, match=r"shape \(N, 3\)"):
        segloc.ObjectMap.from_points(np.zeros((4, 2)))
    with pytest.raises(segloc.SegLocError, match="index 1"):
        segloc.ObjectMap.from_points(np.array([[0, 0, 0], [np.nan, 0, 0]], dtype=float))
    with pytest.raises(segloc.SegLocError, match="2 points but 3 sizes"):
        segloc.ObjectMap.from_points(np.zeros((2, 3)), sizes=np.ones(3))
    m = segloc.ObjectMap.from_points(np.random.default_rng(0).normal(size=(10, 3)))
    with pytest.raises(segloc.SegLocError, match="not a rotation"):
        m.transformed(np.diag([2.0, 1.0, 1.0, 1.0]), "scaled")
    with pytest.raises(segloc.SegLocError, match="unknown field"):
        segloc.RelocalizeConfig(verification={"min_inlier": 3})
    with pytest.raises(segloc.SegLocError, match="dof must be 4, 6"):
        segloc.RelocalizeConfig(dof=5)
    with pytest.raises(segloc.SegLocError, match="min_inliers"):
        segloc.RelocalizeConfig.from_toml("[verification]\nmin_inliers = 'many'\n")


def test_invalid_relocalization_input_raises(data_dir):
    prior = segloc.read_traverse(traverse(data_dir, 3))
    tiny = segloc.ObjectMap.from_points(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]])
    # a query too small to fix a transform is a refusal, not an error
    answer = segloc.Relocalizer(prior).relocalize(tiny)
    assert not answer.accepted and answer.refusal_code == "too_few_landmarks"
    assert "query map has 2 landmarks" in answer.refusal
    with pytest.raises(segloc.SegLocError, match="prior map has 2 landmarks"):
        segloc.Relocalizer(tiny)
    tilted = segloc.ObjectMap.from_points(prior.points, gravity_aligned=False)
    with pytest.raises(segloc.SegLocError, match="gravity-aligned"):
        segloc.Relocalizer(prior, segloc.RelocalizeConfig(dof=4)).relocalize(tilted)
    with pytest.raises(segloc.SegLocError, match="reference"):
        segloc.merge_maps([prior, prior], reference=5)
