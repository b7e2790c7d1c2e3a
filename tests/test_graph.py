"""The pose graph over keyframes (issue 13): edges from the front end's keyframe fits, a known
closure on a simulated loop, g2o out and in."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuzzypos import Config, Positioner, sim
from fuzzypos.demo import DemoSettings
from fuzzypos.geometry import relative
from fuzzypos.pipeline import Estimate

gtsam = pytest.importorskip("gtsam")

from fuzzypos.graph import PoseGraph, PoseGraphError, read_g2o  # noqa: E402


@pytest.fixture(scope="module")
def loop() -> tuple[sim.SimulatedRun, list[Estimate]]:
    """One lap of a 4 m circle in the gym at 0.5 m/s (503 scans): the front end drifts by a
    few centimetres, odometry by a metre."""
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(4.0, 1.0, 0.5), DemoSettings().scanner,
        sim.SlipModel(), 0,
    )  # fmt: skip
    pos = Positioner(Config())
    return run, [pos.update(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)]


def _end_error(poses: np.ndarray, truth: np.ndarray) -> float:
    return float(np.hypot(*(poses[-1, :2] - truth[-1, :2])))


def test_keyframes_and_edges_follow_the_front_end(loop) -> None:
    _, ests = loop
    graph = PoseGraph.from_estimates(ests)
    flagged = [k for k, e in enumerate(ests) if e.keyframe]
    assert flagged[0] == 0 and [kf.scan for kf in graph.keyframes] == flagged
    assert 15 <= len(graph) <= 40  # a keyframe every metre or 30° along 25 m
    assert len(graph.edges) == len(graph) - 1 and not graph.closures
    for e in graph.edges:
        a, b = graph.keyframes[e.i], graph.keyframes[e.j]
        assert e.j == e.i + 1
        np.testing.assert_allclose(e.measured, relative(a.pose, b.pose), atol=1e-12)
        sigma = np.sqrt(np.diag(e.covariance))
        assert np.all(sigma > 0) and sigma[0] < 0.05 and sigma[2] < np.radians(2)
    # unoptimised, every scan follows its keyframe back onto the front end's pose
    np.testing.assert_allclose(graph.trajectory(), graph.frontend_trajectory(), atol=1e-9)


def test_a_known_closure_brings_the_end_back(loop, tmp_path: Path) -> None:
    run, ests = loop
    graph = PoseGraph.from_estimates(ests)
    truth = run.true_poses
    before = _end_error(graph.frontend_trajectory(), truth)
    i, j = 0, len(graph) - 1
    measured = relative(truth[graph.keyframes[i].scan], truth[graph.keyframes[j].scan])
    # a closure as precise as one scan fit: 1 cm, 0.2°
    graph.add_closure(i, j, measured, np.diag([1e-4, 1e-4, np.radians(0.2) ** 2]))
    graph.optimize()
    after = _end_error(graph.trajectory(), truth)
    assert graph.closure_weights == [pytest.approx(1.0)]
    assert before > 0.02, before  # the front end has drifted
    assert after < 0.015 and after < before / 2, (before, after)

    path = tmp_path / "graph.g2o"
    graph.write_g2o(path)
    poses, edges = read_g2o(path)
    np.testing.assert_allclose(poses, graph.poses, atol=1e-6)
    assert len(edges) == len(graph.edges) and edges[-1].closure
    for a, b in zip(edges, graph.edges):
        assert (a.i, a.j) == (b.i, b.j)
        np.testing.assert_allclose(a.information, b.information, rtol=1e-6)
    # gtsam reads it as a 2D graph too
    read_graph, initial = gtsam.readG2o(str(path), False)
    assert read_graph.size() == len(graph.edges) and initial.size() == len(graph)


def test_a_keyframe_without_a_covariance_is_refused(loop) -> None:
    from dataclasses import replace

    _, ests = loop
    k = next(k for k, e in enumerate(ests) if e.keyframe and k > 0)
    broken = [*ests[:k], replace(ests[k], keyframe_covariance=None)]
    with pytest.raises(PoseGraphError, match=f"scan {k}"):
        PoseGraph.from_estimates(broken)


def test_a_bad_g2o_line_names_the_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.g2o"
    path.write_text("VERTEX_SE2 0 0 0 0\nEDGE_SE3 0 1\n", encoding="utf-8")
    with pytest.raises(PoseGraphError, match=r"bad\.g2o:2"):
        read_g2o(path)
