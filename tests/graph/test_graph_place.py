"""The place descriptor of loop closure (issue 13): rotation-invariant, its best shift the
heading between two views of a place, and its candidates find a revisit the graph's guess has
lost by metres."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzypos import Config, Positioner, sim
from fuzzypos.geometry import compose, relative, transform_points
from fuzzypos.graph.place import PlaceIndex, place_descriptor
from fuzzypos.jobs import DemoSettings

RINGS, SECTORS, RANGE = 20, 60, 10.0
WIDTH = math.tau / SECTORS


def _room(seed: int) -> np.ndarray:
    """Points on the walls and furniture of a random room around the origin."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(8):
        a, b = rng.uniform(-7, 7, 2), rng.uniform(-7, 7, 2)
        t = np.linspace(0, 1, 60)[:, None]
        out.append(a + t * (b - a))
    return np.concatenate(out)


def _view(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """The points seen from ``pose`` (x, y, θ), in its frame."""
    return transform_points(relative(pose, np.zeros(3)), points)


@given(seed=st.integers(0, 10_000), turn=st.integers(-SECTORS // 2 + 1, SECTORS // 2 - 1))
def test_a_turn_by_whole_sectors_gives_the_same_descriptor_and_the_turn(seed, turn) -> None:
    pts = _room(seed)
    here = place_descriptor(pts, RINGS, SECTORS, RANGE)
    turned = place_descriptor(_view(pts, np.array([0.0, 0.0, turn * WIDTH])), RINGS, SECTORS, RANGE)
    index = PlaceIndex([here, place_descriptor(_room(seed + 1), RINGS, SECTORS, RANGE)])
    distance, heading = index.compare(turned, np.array([0, 1]), 0.5)
    assert distance[0] == pytest.approx(0.0, abs=1e-9)
    assert heading[0] == pytest.approx(turn * WIDTH, abs=1e-9)
    assert distance[1] > 0.1  # another room is not this one


@given(
    seed=st.integers(0, 10_000),
    turn=st.floats(-math.pi + 0.1, math.pi - 0.1),
    dx=st.floats(-0.3, 0.3),
    dy=st.floats(-0.3, 0.3),
)
def test_any_turn_and_a_small_step_give_the_heading_to_a_sector(seed, turn, dx, dy) -> None:
    pts = _room(seed)
    here = place_descriptor(pts, RINGS, SECTORS, RANGE)
    there = place_descriptor(_view(pts, np.array([dx, dy, turn])), RINGS, SECTORS, RANGE)
    others = [place_descriptor(_room(seed + k), RINGS, SECTORS, RANGE) for k in (1, 2, 3)]
    distance, heading = PlaceIndex([here, *others]).compare(there, np.arange(4), 0.5)
    assert abs(math.remainder(heading[0] - turn, math.tau)) <= 1.5 * WIDTH
    assert distance[0] < distance[1:].min()


@given(seed=st.integers(0, 10_000), pick=st.lists(st.integers(0, 4), min_size=1, max_size=5))
def test_an_index_grown_a_keyframe_at_a_time_compares_as_one_built_at_once(seed, pick) -> None:
    """Online the index grows by one descriptor per keyframe: the same distances and headings
    as an index of them all, for any subset compared."""
    ds = [place_descriptor(_room(seed + k), RINGS, SECTORS, RANGE) for k in range(5)]
    grown = PlaceIndex(ds[:1])
    for d in ds[1:]:
        grown.append(d)
    query = place_descriptor(_view(_room(seed + 2), np.array([0.1, -0.2, 0.7])), RINGS, SECTORS,
                             RANGE)  # fmt: skip
    among = np.array(pick, dtype=np.intp)
    for a, b in zip(grown.compare(query, among, 0.5), PlaceIndex(ds).compare(query, among, 0.5)):
        np.testing.assert_array_equal(a, b)
    assert len(grown) == 5
    with pytest.raises(ValueError, match="differ"):
        grown.append(place_descriptor(_room(0), 10, 30, RANGE))


def test_a_descriptor_needs_a_grid() -> None:
    with pytest.raises(ValueError, match="rings"):
        place_descriptor(np.zeros((3, 2)), 0, SECTORS, RANGE)
    with pytest.raises(ValueError, match="differ"):
        PlaceIndex(
            [place_descriptor(_room(0), 10, 30, RANGE), place_descriptor(_room(0), 20, 30, RANGE)]
        )


gtsam = pytest.importorskip("gtsam")

from fuzzypos.graph import LoopCloser, PoseGraph  # noqa: E402


@pytest.fixture(scope="module")
def lap():
    """1.4 laps of a 4 m circle in the gym (the front end drifts by centimetres), then the
    drift the place descriptor is for (:func:`_drifted`)."""
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(4.0, 1.4, 0.5), DemoSettings().scanner,
        sim.SlipModel(), 0,
    )  # fmt: skip
    pos = Positioner(Config())
    ests = [pos.update(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)]
    return run, ests


def _drifted(ests, turn: float = math.radians(90.0)) -> PoseGraph:
    """The graph with every edge turned by an equal share of ``turn`` and its heading variance
    grown so the whole turn is two standard deviations: a drift the chain's covariance
    allows, but metres beyond the graph's guess at the revisits."""
    graph = PoseGraph.from_estimates(ests)
    n = len(graph.edges)
    for k, e in enumerate(graph.edges):
        cov = e.covariance.copy()
        cov[2, 2] += (turn / 2.0) ** 2 / n
        graph.edges[k] = replace(
            e, measured=e.measured + np.array([0.0, 0.0, turn / n]), covariance=cov
        )
    poses = [graph.poses[0]]
    for edge in graph.edges:
        poses.append(compose(poses[-1], edge.measured))
    graph.poses = np.array(poses)
    graph.keyframes = [replace(kf, pose=p) for kf, p in zip(graph.keyframes, graph.poses)]
    return graph


def test_place_candidates_find_the_revisit_the_graph_lost(lap) -> None:
    run, ests = lap
    truth = run.true_poses
    results = {}
    for place in (False, True):
        graph = _drifted(ests)
        scans = [kf.scan for kf in graph.keyframes]
        start = truth[scans[0]]
        off = [np.hypot(*(relative(graph.poses[0], p) - relative(start, truth[s]))[:2])
               for p, s in zip(graph.poses, scans)]  # fmt: skip
        assert max(off) > 4.0  # the drift is beyond the verification's search (±3 m)
        cfg = Config().with_overrides({"loop_closure": {"place_recognition": place}})
        closer = LoopCloser(cfg)
        closures = closer.run(graph)
        for c in closures:
            true = relative(truth[scans[c.i]], truth[scans[c.j]])
            assert np.hypot(*(c.measured[:2] - true[:2])) < 0.05, (c, true)
        end = relative(graph.poses[0], graph.poses[-1])
        true_end = relative(truth[scans[0]], truth[scans[-1]])
        results[place] = (closures, float(np.hypot(*(end[:2] - true_end[:2]))))
    closures, end_error = results[True]
    assert any(c.source == "place" and c.weight > 0.5 for c in closures)
    assert all(c.agreed is not None for c in closures if c.source == "place")
    assert end_error < 0.25 and end_error < results[False][1] / 10, (results[False][1], end_error)
