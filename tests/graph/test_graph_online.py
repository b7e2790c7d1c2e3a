"""Loop closure online (issue 13): :class:`~fuzzypos.graph.OnlineMapper` returns after each
scan its latest optimised pose; after the loop closes it is back near the truth, its final
trajectory is the offline path's, its online poses are the front end's until the first
closure, and a false closure does not bend it."""

from __future__ import annotations

import sys
from types import SimpleNamespace

import numpy as np
import pytest

from fuzzypos import Config, Positioner, sim
from fuzzypos.geometry import Pose2D, relative
from fuzzypos.graph import GraphDependencyError, OnlineMapper, PoseGraph, ScanStore, close_loops
from fuzzypos.jobs import DemoSettings

pytest.importorskip("gtsam", reason="loop closure needs gtsam (pip install 'fuzzypos[graph]')")

from test_graph import TWIN_SHIFT, _twin_rooms


def _errors(poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(*(poses[:, :2] - truth[: len(poses), :2]).T)


@pytest.fixture(scope="module")
def lap():
    """One lap of a 4 m circle in the gym (503 scans; odometry off by a metre at the end),
    run online."""
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(4.0, 1.0, 0.5), DemoSettings().scanner,
        sim.SlipModel(), 0,
    )  # fmt: skip
    mapper = OnlineMapper(Config())
    updates = [mapper.update(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)]
    return run, mapper, updates


def test_the_latest_poses_come_back_once_the_loop_closes(lap) -> None:
    run, mapper, updates = lap
    truth = run.true_poses
    closed = [k for k, u in enumerate(updates) if u.closed]
    assert closed, "the lap's end closes on its start"
    assert all(updates[k].keyframe for k in closed)  # closures are tried at keyframes
    assert [u.closures for u in updates][-1] == len(mapper.closures) >= len(closed)
    online, front = mapper.online_poses(), mapper.frontend_poses()
    assert len(online) == len(front) == len(run.scans)
    np.testing.assert_allclose(
        [u.pose.as_array() for u in updates], online, atol=1e-9
    )  # what update() gave is what online_poses() remembers
    # once the loop has closed: its first closure may come from across the circle, from a
    # viewpoint metres away (true to 3 cm, the closures' covariance floor), before the lap's end
    # closes on its start
    after = slice(closed[-1], None)
    err_online = _errors(online[after], truth[after])
    err_front = _errors(front[after], truth[after])
    assert err_front.mean() > 0.02, err_front.mean()  # the front end has drifted by then
    assert err_online.mean() < 0.015 and err_online.mean() < err_front.mean() / 2, (
        err_online.mean(),
        err_front.mean(),
    )


def test_online_poses_are_the_front_ends_until_the_first_closure(lap) -> None:
    run, mapper, updates = lap
    first = next(k for k, u in enumerate(updates) if u.closed)
    np.testing.assert_allclose(mapper.online_poses()[:first], mapper.frontend_poses()[:first],
                               atol=1e-9)  # fmt: skip
    # the front end is the plain Positioner's: the corrections never reach it
    pos = Positioner(Config())
    plain = [pos.update(s, run.odometry_pose(k)).pose.as_array() for k, s in enumerate(run.scans)]
    np.testing.assert_array_equal(mapper.frontend_poses(), np.array(plain))


def test_the_final_trajectory_is_the_offline_paths(lap) -> None:
    run, mapper, _ = lap
    result = mapper.finish()
    pos = Positioner(Config())
    estimates = [pos.update(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)]
    graph, store = PoseGraph.from_estimates(estimates), ScanStore(Config())
    for est, scan in zip(estimates, run.scans):
        store.add(est.features, scan.angle_increment, est.keyframe_covariance)
    offline = close_loops(graph, Config(), store)
    assert len(offline.closures) == len(result.closures)
    assert np.abs(result.poses - offline.poses).max() < 0.005
    # every scan realigned to the closed map, from the optimised trajectory
    assert result.summary["realigned_scans"] > 0.9 * len(run.scans)
    assert offline.summary["realigned_scans"] > 0.9 * len(run.scans)
    moved = np.hypot(*(result.poses[:, :2] - mapper.trajectory()[:, :2]).T)
    assert 0.0 < moved.max() < Config().refinement.max_correction
    assert _errors(result.poses, run.true_poses)[-1] < 0.02
    assert result.summary["mode"] == "online" and result.online is not None
    # the map is drawn from more scans than the keyframes, every 0.25 m or 10°
    assert result.map_scans is not None and len(result.map_scans) > 2 * len(mapper.graph)


def test_a_false_closure_online_is_weighed_out() -> None:
    """Two identical rooms; in the second, each keyframe told it is in the first (the search
    started at the twin's place): the closures that verify there disagree with the graph, the
    batch GNC gives them no weight and ISAM2 goes on without them."""
    loop_a = [(-1.5, 0.0), (1.5, 0.0), (1.5, -1.0), (-1.5, -1.0), (-1.5, 0.0), (1.5, 0.0)]
    path = sim.CommandedPath.waypoints(loop_a + [(x + TWIN_SHIFT, y) for x, y in loop_a], 0.5)
    run = sim.simulate_run(_twin_rooms(), path, DemoSettings().scanner, sim.SlipModel(), 0)
    truth = run.true_poses
    mapper = OnlineMapper(Config())
    closer, honest = mapper.closer, mapper.closer.close
    false = []

    def close(graph: PoseGraph, j: int):
        if truth[graph.keyframes[j].scan, 0] < TWIN_SHIFT - 3.0:
            return honest(graph, j)
        twin = graph.poses[j] - np.array([TWIN_SHIFT, 0.0, 0.0])
        i = int(np.argmin(np.hypot(*(graph.poses[:j, :2] - twin[:2]).T)))
        found = closer.verify(graph, i, j, predicted=relative(graph.poses[i], twin))
        if found is not None:
            graph.add_closure(found.i, found.j, found.measured, found.covariance)
            closer.closures.append(found)
            false.append(found)
        return found

    closer.close = close  # type: ignore[method-assign]
    for k, s in enumerate(run.scans):
        mapper.update(s, run.odometry_pose(k))
    assert len(false) >= 3 and mapper.batch_optimisations >= 1
    online, front = mapper.online_poses(), mapper.frontend_poses()
    assert np.hypot(*(online[:, :2] - front[:, :2]).T).max() < 0.1  # not dragged 14 m
    result = mapper.finish()
    weights = {(c.i, c.j): c.weight for c in result.closures}
    assert max(weights[(c.i, c.j)] for c in false) < 0.1, weights
    assert _errors(result.poses, truth).max() < 0.1


def test_update_checks_its_inputs_and_gtsam(monkeypatch) -> None:
    mapper = OnlineMapper(Config())
    with pytest.raises(TypeError):
        mapper.update("not a scan", Pose2D(0.0, 0.0, 0.0))  # type: ignore[arg-type]
    monkeypatch.setitem(sys.modules, "gtsam", None)  # import gtsam now raises ImportError
    with pytest.raises(GraphDependencyError, match=r"pip install 'fuzzypos\[graph\]'"):
        OnlineMapper(Config())


def test_every_closure_the_closer_adds_goes_into_isam2() -> None:
    """A place closure is added with the closure it agreed with, two edges at once: both go
    into ISAM2 (its factors: the anchor, the chain and every closure), not only the last."""
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(4.0, 1.0, 0.5), DemoSettings().scanner,
        sim.SlipModel(), 0,
    )  # fmt: skip
    mapper = OnlineMapper(Config())
    added: list[tuple[int, int]] = []

    def close_twice(graph: PoseGraph, j: int) -> SimpleNamespace | None:
        """Two closures of keyframe ``j`` that agree with the graph (no batch re-solve)."""
        if j < 5 or added:
            return None
        for i in (j - 3, j - 2):
            graph.add_closure(i, j, relative(graph.poses[i], graph.poses[j]), np.eye(3) * 1e-4)
            added.append((i, j))
        measured = relative(graph.poses[j - 2], graph.poses[j])
        return SimpleNamespace(i=j - 2, j=j, measured=measured, covariance=np.eye(3) * 1e-4)

    mapper.closer.close = close_twice  # type: ignore[method-assign]
    for k, s in enumerate(run.scans[:150]):
        mapper.update(s, run.odometry_pose(k))
    assert len(added) == 2
    factors = mapper._isam.getFactorsUnsafe()
    n_factors = sum(1 for f in range(factors.size()) if factors.at(f) is not None)
    assert n_factors == 1 + len(mapper.graph.edges), (n_factors, len(mapper.graph.edges))
