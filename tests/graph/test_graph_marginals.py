"""The optimised poses' covariance (``run --loop-closure``): the pose graph's marginals, each
scan's carried from its keyframe with the front end's covariance relative to it and rotated
into the map frame; honest against a simulated loop's truth, the chain's propagation on an
open chain, and what ``covariance_optimised.csv`` holds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from fuzzypos import Config, sim
from fuzzypos.geometry import (
    compose,
    compose_steps,
    covariance_to_parent,
    covariances_to_parent,
    relative,
    wrap_angle,
)
from fuzzypos.jobs import DemoSettings

pytest.importorskip("gtsam")

from fuzzypos.graph import OnlineMapper, PoseGraph
from fuzzypos.graph.outputs import OPTIMISED_COVARIANCE_COLUMNS


@pytest.fixture(scope="module")
def loop():
    """One lap of a 4 m circle in the gym at 0.5 m/s (503 scans), closed online."""
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(4.0, 1.0, 0.5), DemoSettings().scanner,
        sim.SlipModel(), 0,
    )  # fmt: skip
    mapper = OnlineMapper(Config())
    estimates = [mapper.update(s, run.odometry_pose(k)).estimate for k, s in enumerate(run.scans)]
    return run, estimates, mapper.finish()


def _d2(poses: np.ndarray, truth: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """The Mahalanobis distance squared of each pose's error (map frame, additive) from the
    truth, the truth moved so its first pose is the estimate's (the graph's gauge)."""
    truth = compose(poses[0], relative(truth[0], truth))
    e = poses - truth
    e[:, 2] = wrap_angle(e[:, 2])
    return np.einsum("ni,nij,nj->n", e, np.linalg.inv(cov), e)


def test_the_optimised_poses_covariance_is_honest_on_a_simulated_loop(loop) -> None:
    run, _, result = loop
    assert result.summary["closures_kept"] >= 1 and result.summary["marginals_error"] is None
    cov = result.covariances
    assert cov is not None and cov.shape == (len(run.scans), 3, 3)
    np.testing.assert_array_equal(cov, np.swapaxes(cov, 1, 2))
    assert np.all(np.linalg.eigvalsh(cov) > 0.0)  # positive definite
    d2 = _d2(result.poses, run.true_poses, cov)
    assert np.mean(d2 < chi2.ppf(0.999, 3)) >= 0.95, np.sort(d2)[-10:]
    assert np.median(d2) >= 0.1, np.median(d2)  # not inflated
    # the first keyframe is the anchor's: µm; the others centimetres
    assert np.sqrt(cov[0].diagonal()).max() < 1e-5
    assert np.all(np.sqrt(cov[len(cov) // 2, [0, 1], [0, 1]]) > 1e-3)


def test_the_marginals_grow_along_an_open_chain_as_its_propagation(loop) -> None:
    """Without closures the marginal of a keyframe is the anchor's carried along the chain
    of edges (right perturbations, in the keyframe's own frame: gtsam's Pose2 convention)."""
    _, estimates, _ = loop
    graph = PoseGraph.from_estimates(estimates[:250])
    graph.optimize("none")
    marginals = graph.marginals()
    assert len(marginals) == len(graph) >= 5
    for j in (1, len(graph) // 2, len(graph) - 1):
        edges = graph.edges[:j]
        steps = np.array([e.measured for e in edges])
        _, sigma = compose_steps(steps, np.array([e.covariance for e in edges]))
        np.testing.assert_allclose(marginals[j], sigma, rtol=1e-4, atol=1e-12)
    position = marginals[:, 0, 0] + marginals[:, 1, 1]
    assert position[0] < 1e-10
    assert np.all(np.diff(marginals[:, 2, 2]) > 0.0)  # the heading's only grows on a chain
    assert position[1] < position[len(graph) // 2] < position[-1]
    # a scan between keyframes: its keyframe's, carried to it, plus its own relative to it
    poses = graph.trajectory()
    scans = graph.scan_covariances(poses, marginals)
    assert np.all(np.linalg.eigvalsh(scans) > 0.0)
    k = next(s for s in range(graph.scans) if graph.owners[s] == 2 and graph.keyframes[2].scan < s)
    assert np.trace(scans[k][:2, :2]) > np.trace(marginals[2][:2, :2])


def test_the_csv_holds_the_map_frame_covariance(loop, tmp_path) -> None:
    run, _, result = loop
    stamps = np.arange(len(run.scans), dtype=float)
    result.write(tmp_path, stamps, "loop", 0.05)
    lines = (tmp_path / "covariance_optimised.csv").read_text().splitlines()
    assert lines[0] == ",".join(OPTIMISED_COVARIANCE_COLUMNS) and len(lines) == len(stamps) + 1
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    np.testing.assert_array_equal(rows[:, 0], stamps)
    c = result.covariances
    np.testing.assert_array_equal(rows[:, 1:], c[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]])


def test_covariances_to_parent_rotates_each_into_its_pose_s_parent() -> None:
    rng = np.random.default_rng(3)
    poses = rng.normal(size=(5, 3))
    a = rng.normal(size=(5, 3, 3))
    covs = a @ np.swapaxes(a, 1, 2)
    got = covariances_to_parent(poses, covs)
    for p, c, g in zip(poses, covs, got, strict=True):
        np.testing.assert_allclose(g, covariance_to_parent(p, c), rtol=1e-12, atol=1e-12)
