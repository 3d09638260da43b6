"""A merge of three real traverses, a pose graph against the CLI, the online localizer."""

import json
import subprocess

import numpy as np

import segloc
from conftest import inverse, traverse


def yaw_pose(x, y, z, yaw):
    t = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    t[:2, :2] = [[c, -s], [s, c]]
    t[:3, 3] = [x, y, z]
    return t


def test_three_agents_merge_into_the_first_frame(data_dir):
    # three rovers, each in its own frame world_from_agent (unknown to the merge)
    agents = [(13, np.eye(4)), (9, yaw_pose(12.0, -7.0, 0.3, 2.1)), (15, yaw_pose(-5.0, 18.0, -0.2, -0.7))]
    maps = [segloc.read_traverse(traverse(data_dir, n)).transformed(inverse(t), "agent") for n, t in agents]
    result = segloc.merge_maps(maps, reference=0)
    assert result.merged_flags == [True, True, True]
    for (_, world_from_agent), placed in zip(agents, result.reference_from_map):
        # reference = agent 0 = world here
        err = inverse(world_from_agent) @ placed
        assert np.linalg.norm(err[:3, 3]) < 0.05
    assert result.fused > 10
    assert len(result.merged) < sum(len(m) for m in maps)
    assert len(result.to_dict()["pairs"]) == 3


def write_loop_g2o(path, n=40, seed=1):
    """A square-ish loop: noisy odometry, one loop closure, the vertices from the odometry."""
    rng = np.random.default_rng(seed)
    info = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400"
    lines, pose = [], np.eye(4)
    step = yaw_pose(1.0, 0.0, 0.0, 2 * np.pi / n)
    for k in range(n):
        q = quat(pose[:3, :3])
        lines.append(f"VERTEX_SE3:QUAT {k} {pose[0, 3]} {pose[1, 3]} {pose[2, 3]} {q}")
        noisy = step @ yaw_pose(*rng.normal(0, 0.02, 3), rng.normal(0, 0.01))
        if k + 1 < n:
            lines.append(f"EDGE_SE3:QUAT {k} {k + 1} 1.0 0 0 {quat(step[:3, :3])} {info}")
        pose = pose @ noisy
    lines.append(f"EDGE_SE3:QUAT {n - 1} 0 1.0 0 0 {quat(step[:3, :3])} {info}")
    path.write_text("\n".join(lines) + "\n")


def quat(r):
    w = np.sqrt(max(1e-12, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    return f"{(r[2, 1] - r[1, 2]) / (4 * w)} {(r[0, 2] - r[2, 0]) / (4 * w)} {(r[1, 0] - r[0, 1]) / (4 * w)} {w}"


def test_pose_graph_as_the_cli(tmp_path, segloc_bin):
    path = tmp_path / "loop.g2o"
    write_loop_g2o(path)
    graph = segloc.optimize_pose_graph(path)
    assert graph.final_cost < graph.initial_cost and graph.final_cost < 1e-6
    assert graph.poses.shape == (40, 4, 4) and graph.ids.tolist() == list(range(40))
    assert np.allclose(graph.poses[0], np.eye(4))  # the gauge: the first pose is fixed
    cli = subprocess.run([segloc_bin, "graph", "optimize", str(path), "--json"], capture_output=True, text=True)
    assert cli.returncode == 0, cli.stderr
    report = json.loads(cli.stdout)
    assert graph.initial_cost == report["initial_cost"]
    assert graph.final_cost == report["final_cost"]
    assert graph.iterations == report["iterations"]
    assert graph.to_dict()["poses"] == 40


def test_localizer_replays_a_drive(tmp_path, segloc_bin):
    drive, prior_path = tmp_path / "drive.jsonl", tmp_path / "prior.map.json"
    subprocess.run(
        [segloc_bin, "sim", "export", "--seed", "3", "--session", "2", "--seconds", "60",
         "-o", str(drive), "--prior-map", str(prior_path)],
        check=True, capture_output=True,
    )
    frames = segloc.read_frames(drive)
    localizer = segloc.Localizer(segloc.read_map(prior_path))
    outputs = [localizer.push_frame(f) for f in frames]
    assert any(o.fixes for o in outputs)
    assert outputs[-1].prior_from_rover.shape == (4, 4)
    session = localizer.finish()
    assert session.poses.shape == (len(frames), 4, 4)
    assert session.attempts[0] >= 1
    try:
        localizer.push_frame(frames[0])
        raise AssertionError("a finished localizer took a frame")
    except segloc.SegLocError as e:
        assert "finished" in str(e)
