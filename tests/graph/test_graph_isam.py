"""Loop closure online never loses a run to ISAM2 (issue 34 item 7): a long chain without a
closure, whose newest pose is metres uncertain in position and a few degrees in heading, is
what gtsam's Cholesky declares indeterminate (the failure fr-clinic met, gtsam issue #406);
QR solves it, and whatever ISAM2 raises is recovered from: every keyframe kept, the poses
finite and the chain's, the failure counted in the summary."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from fuzzypos import Config
from fuzzypos.geometry import Pose2D, compose
from fuzzypos.graph import OnlineMapper
from fuzzypos.pipeline import Estimate

pytest.importorskip("gtsam", reason="loop closure needs gtsam (pip install 'fuzzypos[graph]')")

INDETERMINATE = "Indeterminate linear system detected while working near variable"


def _straight_chain(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` edges of a robot driving straight on, a metre a keyframe with a few milliradians
    of turn, and their covariance (3 mm² … in translation, (2.8 mrad)² in heading); the
    keyframes' poses (the edges composed, exactly consistent: the graph's optimum)."""
    rng = np.random.default_rng(seed)
    edges = np.column_stack((np.ones(n), rng.normal(0.0, 0.05, n), rng.normal(0.0, 0.02, n)))
    cov = np.diag([3e-5, 3e-5, 8e-6])
    poses = [np.zeros(3)]
    for e in edges:
        poses.append(compose(poses[-1], e))
    return edges, cov, np.array(poses)


def _estimate(k: int, pose: np.ndarray, cov: np.ndarray) -> Estimate:
    p = Pose2D.from_array(pose)
    return Estimate(
        stamp=float(k), pose=p, increment=p, prior=p, n_pairs=10, degraded=False,
        keyframe_covariance=cov, keyframe=True,
    )  # fmt: skip


def _mapper(factorization: str = "qr") -> OnlineMapper:
    """A mapper without closures (none is tried) nor the realignment (no scans kept)."""
    cfg = Config()
    cfg = replace(
        cfg,
        loop_closure=replace(cfg.loop_closure, realign=False, isam_factorization=factorization),
    )
    mapper = OnlineMapper(cfg)
    mapper.closer.close = lambda graph, j: None  # type: ignore[method-assign]
    return mapper


def _feed(mapper: OnlineMapper, poses: np.ndarray, cov: np.ndarray) -> None:
    for k, pose in enumerate(poses):
        mapper.add(_estimate(k, pose, cov))


class _FailingISAM2:
    """gtsam's ISAM2 whose updates raise gtsam's indeterminate-system error when ``fail``
    says so (called with the update's count over every instance)."""

    calls = 0

    def __init__(self, isam: Any, fail: Any) -> None:
        self._isam, self._fail = isam, fail

    def update(self, *args: Any) -> None:
        type(self).calls += 1
        if self._fail(type(self).calls):
            raise RuntimeError(f"\n{INDETERMINATE}\n12 (Symbol: 12).\n")
        self._isam.update(*args)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._isam, name)


def _failing(mapper: OnlineMapper, monkeypatch: pytest.MonkeyPatch, fail: Any) -> None:
    _FailingISAM2.calls = 0
    make = mapper._new_isam
    monkeypatch.setattr(mapper, "_new_isam", lambda: _FailingISAM2(make(), fail))


def test_a_long_straight_chain_is_solved_by_qr_where_cholesky_fails() -> None:
    """1,100 keyframes straight on, no closure: by the end, the newest pose's sideways
    position is some 50 m uncertain and its heading 5°, nearly all of it the same error (the
    heading times the lever arm). ISAM2 by Cholesky declares the system indeterminate there
    (on such chains between the 900th and the 1,100th keyframe); by QR it is solved. Either
    way the run goes on, every keyframe at the chain's pose."""
    _, cov, truth = _straight_chain(1100)
    qr, chol = _mapper("qr"), _mapper("cholesky")
    _feed(qr, truth, cov)
    _feed(chol, truth, cov)
    assert qr.isam_recoveries["count"] == 0, qr.isam_recoveries
    recoveries = chol.isam_recoveries
    assert recoveries["count"] >= 1 and recoveries["factorization"] == "cholesky"
    assert INDETERMINATE in recoveries["first_message"]
    assert 800 <= recoveries["first_keyframe"] <= 1100, recoveries
    for mapper in (qr, chol):
        assert len(mapper.graph) == len(truth) and mapper._estimate.shape == truth.shape
        assert np.all(np.isfinite(mapper.trajectory()))
        np.testing.assert_allclose(mapper._estimate[:, :2], truth[:, :2], atol=1e-6)
        np.testing.assert_allclose(np.cos(mapper._estimate[:, 2] - truth[:, 2]), 1.0, atol=1e-12)


def test_an_isam2_failure_is_recovered_by_rebuilding_it(monkeypatch) -> None:
    """The 30th update raises: ISAM2 is rebuilt over the whole graph from its last estimate
    and goes on; every keyframe is kept at the chain's pose, the failure counted."""
    _, cov, truth = _straight_chain(59, seed=1)
    mapper = _mapper()
    _failing(mapper, monkeypatch, lambda call: call == 30)
    _feed(mapper, truth, cov)
    rec = mapper.isam_recoveries
    assert rec["count"] == 1 and rec["batch_solves"] == 0, rec
    assert rec["first_keyframe"] == 29  # the first update is the anchor's, keyframe 0
    assert rec["first_message"].startswith(INDETERMINATE)
    assert isinstance(mapper._isam, _FailingISAM2)  # rebuilt, and updated since
    assert len(mapper.graph) == 60 and mapper._estimate.shape == (60, 3)
    np.testing.assert_allclose(mapper._estimate, truth, atol=1e-6)
    online = mapper.online_poses()
    np.testing.assert_allclose(online, truth, atol=1e-6)  # every scan was output
    summary = mapper.finish().summary
    assert summary["isam_recoveries"] == rec
    assert summary["keyframes"] == 60


def test_where_the_rebuild_fails_too_a_batch_solve_stands_in(monkeypatch) -> None:
    """Updates 20 to 25 raise (the update, then the rebuild, at two keyframes in a row...):
    the graph is solved in batch, ISAM2 rebuilt at the next update, and nothing is lost."""
    _, cov, truth = _straight_chain(39, seed=2)
    mapper = _mapper()
    _failing(mapper, monkeypatch, lambda call: 20 <= call <= 25)
    _feed(mapper, truth, cov)
    rec = mapper.isam_recoveries
    assert rec["count"] == 6 and rec["batch_solves"] >= 2, rec
    assert mapper._isam is not None  # back to ISAM2 once its updates succeed
    assert len(mapper.graph) == 40
    np.testing.assert_allclose(mapper._estimate, truth, atol=1e-6)
    assert np.all(np.isfinite(mapper.trajectory()))


def test_an_estimate_that_is_not_finite_is_a_failure(monkeypatch) -> None:
    """ISAM2 returning NaN poses (an ill-conditioned solve that did not raise) is recovered
    from like an exception: the output stays finite."""
    _, cov, truth = _straight_chain(29, seed=3)
    mapper = _mapper()
    real = mapper._g.utilities.extractPose2
    calls = {"n": 0}

    def extract(values: Any) -> np.ndarray:
        calls["n"] += 1
        out = np.asarray(real(values), dtype=float)
        return out * np.nan if calls["n"] == 15 else out

    monkeypatch.setattr(mapper._g.utilities, "extractPose2", extract)
    _feed(mapper, truth, cov)
    rec = mapper.isam_recoveries
    assert rec["count"] == 1 and "not finite" in rec["first_message"], rec
    np.testing.assert_allclose(mapper._estimate, truth, atol=1e-6)
