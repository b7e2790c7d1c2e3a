"""``fuzzypos run --bag-out`` per REP-105 (issue 35): the frames named (``--base-frame``,
``--odom-frame``, ``--map-frame``, else the input bag's, else ``base_link``/``odom``/``map``),
the pose covariance in ROS's order, and with ``--loop-closure`` the optimised poses and
``map → odom`` on /tf, read back with rosbags."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.geometry import compose, wrap_angle
from fuzzypos.io import OdometryBagWriter, read_tum
from fuzzypos.io.rosbag_write import UNUSED_VARIANCE
from helpers import make_bag, odd_frames, one_line_error, write_sim_log

runner = CliRunner()
KINDS = {"ros1": "out.bag", "sqlite3": "out_sqlite", "mcap": "out_mcap"}


def _read(path: Path) -> dict[str, list[Any]]:
    """topic → messages, in the bag's order."""
    out: dict[str, list[Any]] = {}
    with AnyReader([path]) as r:
        for conn, _, raw in r.messages():
            out.setdefault(conn.topic, []).append(r.deserialize(raw, conn.msgtype))
    return out


def _stamp(h: Any) -> int:
    return h.stamp.sec * 1_000_000_000 + h.stamp.nanosec


def _pose(p: Any) -> np.ndarray:
    """(x, y, yaw) of a geometry_msgs Pose or Transform."""
    t = getattr(p, "position", None) or p.translation
    q = getattr(p, "orientation", None) or p.rotation
    return np.array([t.x, t.y, 2.0 * math.atan2(q.z, q.w)])


def _transforms(tf_msgs: list[Any]) -> dict[tuple[str, str], dict[int, np.ndarray]]:
    """(parent, child) → stamp (ns) → (x, y, yaw), from /tf."""
    out: dict[tuple[str, str], dict[int, np.ndarray]] = {}
    for m in tf_msgs:
        for tr in m.transforms:
            key = (tr.header.frame_id, tr.child_frame_id)
            out.setdefault(key, {})[_stamp(tr.header)] = _pose(tr.transform)
    return out


def _same_pose(a: np.ndarray, b: np.ndarray, atol: float = 1e-9) -> None:
    np.testing.assert_allclose(a[..., :2], b[..., :2], atol=atol, rtol=0)
    np.testing.assert_allclose(wrap_angle(a[..., 2] - b[..., 2]), 0.0, atol=atol)


def _check_map_to_odom(msgs: dict[str, list[Any]], frames: tuple[str, str, str]) -> np.ndarray:
    """map → odom ∘ odom → base at each stamp is the optimised pose on /fuzzypos/pose;
    returns the optimised poses."""
    base, odom, map_ = frames
    tf = _transforms(msgs["/tf"])
    assert set(tf) == {(odom, base), (map_, odom)}
    optimised = msgs["/fuzzypos/pose"]
    assert all(m.header.frame_id == map_ for m in optimised)
    assert len(tf[(map_, odom)]) == len(tf[(odom, base)]) == len(optimised)
    for m in optimised:
        t = _stamp(m.header)
        _same_pose(compose(tf[(map_, odom)][t], tf[(odom, base)][t]), _pose(m.pose.pose))
        c = np.asarray(m.pose.covariance).reshape(6, 6)  # z, roll, pitch: unknown
        np.testing.assert_array_equal(c[[2, 3, 4], [2, 3, 4]], UNUSED_VARIANCE)
    return np.array([_pose(m.pose.pose) for m in optimised])


@pytest.mark.parametrize("kind", KINDS)
def test_writer_frames_covariance_and_map_to_odom(tmp_path, kind):
    path = tmp_path / KINDS[kind]
    frames = ("chassis", "wheels", "world")
    front = [(0.5 * k, -0.2 * k, 2.8 - 1.3 * k) for k in range(6)]
    optimised = [(x + 0.1 * k, y - 0.05 * k, th + 0.02 * k) for k, (x, y, th) in enumerate(front)]
    cov = np.array([[1.0, 0.2, 0.03], [0.2, 2.0, -0.04], [0.03, -0.04, 0.05]]) * 1e-4
    with OdometryBagWriter(path, kind, frame_id="wheels", child_frame_id="chassis",
                           map_frame_id="world") as w:  # fmt: skip
        for k, p in enumerate(front):
            w.write(100.0 + 0.2 * k, p, cov)
        for k, (p, f) in enumerate(zip(optimised, front)):
            w.write_optimised(100.0 + 0.2 * k, p, f)
    assert (w.written, w.optimised_written) == (6, 6)
    msgs = _read(path)
    assert set(msgs) == {"/fuzzypos/odom", "/tf", "/fuzzypos/pose"}
    for m in msgs["/fuzzypos/odom"]:
        assert (m.header.frame_id, m.child_frame_id) == ("wheels", "chassis")
        c = np.asarray(m.pose.covariance)  # ROS's order: x y z roll pitch yaw, row-major
        assert (c[0], c[1], c[5], c[7], c[11], c[35]) == tuple(
            cov[i, j] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
        )
        assert c[14] == c[21] == c[28] == UNUSED_VARIANCE  # z, roll, pitch: unobserved
        c6 = c.reshape(6, 6)
        assert np.all(c6[2:5, [0, 1, 5]] == 0.0) and np.all(c6[[0, 1, 5], 2:5] == 0.0)
    got = _check_map_to_odom(msgs, frames)
    _same_pose(got, np.array(optimised))
    for m in msgs["/fuzzypos/pose"]:  # written without a covariance: unknown
        np.testing.assert_array_equal(np.reshape(m.pose.covariance, (6, 6)), np.eye(6) * 1e6)


def test_writer_without_optimised_poses_has_no_pose_topic(tmp_path):
    with OdometryBagWriter(tmp_path / "a.bag") as w:
        w.write(1.0, (0.0, 0.0, 0.0), np.eye(3) * 1e-4)
    msgs = _read(tmp_path / "a.bag")
    assert set(msgs) == {"/fuzzypos/odom", "/tf"}
    tr = msgs["/tf"][0].transforms[0]
    assert (tr.header.frame_id, tr.child_frame_id) == ("odom", "base_link")


# -- the run --------------------------------------------------------------------------------
def test_run_takes_the_frames_from_the_input_bag(tmp_path):
    bag = make_bag(tmp_path, "ros2-sqlite3", odd_frames)
    out, res = tmp_path / "out.bag", tmp_path / "res"
    r = runner.invoke(app, ["run", str(bag), "--results", str(res), "--bag-out", str(out)])
    assert r.exit_code == 0, r.output
    msgs = _read(out)
    assert set(msgs) == {"/fuzzypos/odom", "/tf"}
    m = msgs["/fuzzypos/odom"][0]
    assert (m.header.frame_id, m.child_frame_id) == ("wheels", "chassis")
    s = json.loads((res / "summary.json").read_text())["bag_out"]
    f = s["frames"]
    assert (f["base"], f["odom"], f["map"]) == ("chassis", "wheels", "world")
    assert f["sources"]["map"] == "/tf: the parent of wheels"
    assert s["topics"] == {"/fuzzypos/odom": len(msgs["/tf"]), "/tf": len(msgs["/tf"])}
    # given frames win; the others still come from the bag
    out2, res2 = tmp_path / "out2.bag", tmp_path / "res2"
    args = ["run", str(bag), "--results", str(res2), "--bag-out", str(out2)]
    r = runner.invoke(app, [*args, "--odom-frame", "odom", "--map-frame", "map"])
    assert r.exit_code == 0, r.output
    m = _read(out2)["/fuzzypos/odom"][0]
    assert (m.header.frame_id, m.child_frame_id) == ("odom", "chassis")
    f = json.loads((res2 / "summary.json").read_text())["bag_out"]["frames"]
    assert f["sources"] == {"base": "the odometry's child_frame_id", "odom": "given",
                            "map": "given"}  # fmt: skip


def test_run_on_a_carmen_log_uses_rep105_names(tmp_path):
    log = tmp_path / "sim.clf"
    write_sim_log(log, laps=0.03)
    out, res = tmp_path / "out.bag", tmp_path / "res"
    r = runner.invoke(app, ["run", str(log), "--results", str(res), "--bag-out", str(out),
                            "--base-frame", "base_footprint"])  # fmt: skip
    assert r.exit_code == 0, r.output
    m = _read(out)["/fuzzypos/odom"][0]
    assert (m.header.frame_id, m.child_frame_id) == ("odom", "base_footprint")
    s = json.loads((res / "summary.json").read_text())
    assert s["bag_out"]["frames"]["map"] == "map" and s["bag_out"]["storage"] == "ros1"


def test_frame_errors_are_one_line(tmp_path):
    log = tmp_path / "sim.clf"
    write_sim_log(log, laps=0.02)
    r = ["run", str(log), "--results", str(tmp_path / "r")]
    one_line_error([*r, "--map-frame", "world"], "--map-frame", "--bag-out")
    bag = ["--bag-out", str(tmp_path / "o.bag")]
    one_line_error([*r, *bag, "--base-frame", "my robot"], "base frame", "without spaces")
    one_line_error([*r, *bag, "--map-frame", "odom"], "must differ")
    assert not (tmp_path / "o.bag").exists() and not (tmp_path / "r").exists()


def test_run_with_loop_closure_writes_the_optimised_poses_and_map_to_odom(tmp_path):
    pytest.importorskip("gtsam")
    log = tmp_path / "loop.clf"
    write_sim_log(log, laps=1.3, seed=0)
    out, res = tmp_path / "out_mcap", tmp_path / "res"
    args = ["run", str(log), "--loop-closure", "--results", str(res), "--bag-out", str(out)]
    r = runner.invoke(app, [*args, "--bag-storage", "mcap", "--map-frame", "world"])
    assert r.exit_code == 0, r.output
    msgs = _read(out)
    assert set(msgs) == {"/fuzzypos/odom", "/tf", "/fuzzypos/pose"}
    stamps, optimised = read_tum(res / "trajectory.tum")[:2]
    _, frontend = read_tum(res / "trajectory_frontend.tum")[:2]
    odom = msgs["/fuzzypos/odom"]  # the front end's, continuous
    _same_pose(np.array([_pose(m.pose.pose) for m in odom]), frontend, atol=1e-6)
    got = _check_map_to_odom(msgs, ("base_link", "odom", "world"))
    _same_pose(got, optimised, atol=1e-6)  # (the TUM file's precision)
    t = np.array([_stamp(m.header) for m in msgs["/fuzzypos/pose"]]) * 1e-9
    np.testing.assert_allclose(t, stamps, atol=1e-6)
    assert np.abs(got - frontend).max() > 1e-4  # loop closure moved the poses
    s = json.loads((res / "summary.json").read_text())["bag_out"]
    assert s["frames"]["map"] == "world" and s["topics"]["/fuzzypos/pose"] == len(stamps)
    # the optimised poses' covariance: covariance_optimised.csv's (map frame), in ROS's order
    rows = np.loadtxt(res / "covariance_optimised.csv", delimiter=",", skiprows=1, ndmin=2)
    np.testing.assert_allclose(rows[:, 0], stamps, atol=1e-6)
    in_bag = np.array([np.reshape(m.pose.covariance, (6, 6)) for m in msgs["/fuzzypos/pose"]])
    upper = in_bag[:, [0, 0, 0, 1, 1, 5], [0, 1, 5, 1, 5, 5]]
    np.testing.assert_array_equal(upper, rows[:, 1:])
    np.testing.assert_array_equal(in_bag[:, [2, 3, 4], [2, 3, 4]], UNUSED_VARIANCE)
    assert np.all(np.linalg.eigvalsh(in_bag[:, [0, 1, 5]][:, :, [0, 1, 5]]) > 0.0)
    assert rows[:, [1, 4]].max() < 1.0  # known: metres at most, not UNUSED_VARIANCE
