"""The covariance honesty benchmark (``benchmarks/bench_honesty.py``): the SE(2) composition of
step covariances (``fuzzypos.geometry``'s, which the benchmark uses) against finite
differences, ``geometry.propagate`` and a Monte-Carlo; the relations it takes and matches;
the counting of gross and confident gross errors on a synthetic run with injected errors; a
missing covariance row; the written report."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzypos.geometry import (
    adjoint,
    compose,
    compose_steps,
    inverse,
    inverse_covariance,
    propagate,
    relative,
)
from fuzzypos.io import Relations, open_log, read_tum, write_tum
from fuzzypos.jobs import run_log
from helpers import load_benchmark, write_relations, write_sim_log


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("bench_honesty")


finite = st.floats(-5.0, 5.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True)
poses = st.tuples(finite, finite, angle).map(np.array)


def random_cov(rng: np.random.Generator, scale: np.ndarray) -> np.ndarray:
    a = rng.normal(size=(3, 3)) * scale[:, None]
    return a @ a.T + np.diag(np.square(scale)) * 0.1


# -- the adjoint and the composition ---------------------------------------------------------
@given(poses)
def test_the_adjoint_moves_a_right_perturbation_through_the_pose(bench, t) -> None:
    """``T ⊕ ε ⊕ ⊖T ≈ Ad(T)·ε``: the adjoint is the finite-difference Jacobian at ε = 0."""
    h = 1e-6
    jac = np.empty((3, 3))
    for k in range(3):
        eps = np.zeros(3)
        eps[k] = h
        plus = compose(compose(t, eps), inverse(t))
        minus = compose(compose(t, -eps), inverse(t))
        jac[:, k] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(adjoint(t), jac, atol=1e-6)


@given(st.lists(poses, min_size=1, max_size=6), st.integers(0, 2**32 - 1))
def test_the_composition_is_geometry_propagate_step_by_step(bench, steps, seed) -> None:
    rng = np.random.default_rng(seed)
    covs = np.array([random_cov(rng, np.array([0.1, 0.1, 0.05])) for _ in steps])
    motion, sigma = compose_steps(np.array(steps), covs)
    pose, expected = steps[0], covs[0]
    for step, cov in zip(steps[1:], covs[1:]):
        expected = propagate(expected, step, cov)
        pose = compose(pose, step)
    np.testing.assert_allclose(motion, pose, atol=1e-9)
    np.testing.assert_allclose(sigma, expected, rtol=1e-9, atol=1e-12)


def monte_carlo(steps: np.ndarray, covs: np.ndarray, n: int, seed: int) -> np.ndarray:
    """The empirical covariance of ``⊖T ⊕ T̂`` with ``T̂`` the composition of the steps each
    perturbed on the right by a sample of its covariance (numpy only)."""
    rng = np.random.default_rng(seed)
    true = np.zeros(3)
    noisy = np.zeros((n, 3))
    for step, cov in zip(steps, covs):
        eps = rng.multivariate_normal(np.zeros(3), cov, size=n)
        noisy = compose(noisy, compose(step, eps))
        true = compose(true, step)
    err = relative(np.broadcast_to(true, noisy.shape), noisy)
    return np.cov(err.T)


def test_the_composition_matches_a_monte_carlo(bench) -> None:
    rng = np.random.default_rng(3)
    steps = np.array([[0.3, 0.05, 0.2], [0.25, -0.1, -0.35], [0.4, 0.0, 0.5], [0.1, 0.2, 1.2]])
    covs = np.array([random_cov(rng, np.array([0.01, 0.01, 0.005])) for _ in steps])
    _, sigma = compose_steps(steps, covs)
    empirical = monte_carlo(steps, covs, 200_000, 4)
    scale = np.sqrt(np.outer(np.diag(sigma), np.diag(sigma)))
    np.testing.assert_allclose(empirical / scale, sigma / scale, atol=0.02)
    # the sign matters: the composition with the adjoint's off-diagonal flipped disagrees
    flipped = np.zeros((3, 3))
    for step, cov in zip(steps, covs):
        a = adjoint(inverse(step))
        a[:2, 2] *= -1
        flipped = a @ flipped @ a.T + cov
    assert np.max(np.abs(empirical - flipped) / scale) > 0.1


def test_the_inverse_covariance_matches_a_monte_carlo(bench) -> None:
    rng = np.random.default_rng(5)
    t = np.array([1.5, -0.7, 0.9])
    cov = random_cov(rng, np.array([0.01, 0.02, 0.01]))
    eps = rng.multivariate_normal(np.zeros(3), cov, size=200_000)
    noisy_inv = inverse(compose(t, eps))
    err = relative(np.broadcast_to(inverse(t), noisy_inv.shape), noisy_inv)
    expected = inverse_covariance(t, cov)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    np.testing.assert_allclose(np.cov(err.T) / scale, expected / scale, atol=0.02)


def test_chi2_quantile(bench) -> None:
    stats = pytest.importorskip("scipy.stats")
    expected = stats.chi2.ppf(0.999, 3)
    assert abs(bench.CHI2_3_999 - expected) <= 1e-12 * expected


# -- the synthetic run -----------------------------------------------------------------------
N_SCANS = 30


def synthetic(step_sigma: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A run of N_SCANS scans 1 s apart turning gently, each step's covariance diagonal."""
    stamps = 100.0 + np.arange(N_SCANS, dtype=float)
    step = np.array([0.2, 0.0, 0.05])
    p = [np.zeros(3)]
    for _ in range(N_SCANS - 1):
        p.append(compose(p[-1], step))
    covs = np.broadcast_to(
        np.diag([step_sigma**2, step_sigma**2, (step_sigma / 5) ** 2]), (N_SCANS, 3, 3)
    ).copy()
    return stamps, np.array(p), covs


def relations_of(
    stamps: np.ndarray, p: np.ndarray, pairs: list[tuple[int, int]], errors: dict | None = None
) -> Relations:
    """Relations of ``p``'s own motion between the pairs, ``errors[k]`` (x, y, θ) composed
    onto relation ``k``'s motion."""
    motion = np.array([relative(p[i], p[j]) for i, j in pairs])
    for k, e in (errors or {}).items():
        motion[k] = compose(motion[k], e)
    return Relations(
        np.array([stamps[i] for i, _ in pairs]), np.array([stamps[j] for _, j in pairs]), motion
    )


def test_an_injected_metre_is_confident_under_a_tiny_covariance_not_under_a_large_one(
    bench,
) -> None:
    stamps, p, _ = synthetic()
    pairs = [(0, 3), (5, 9), (10, 12), (20, 21)]
    rel = relations_of(stamps, p, pairs, {1: np.array([1.0, 0.0, 0.0])})
    for sigma, confident in ((1e-3, 1), (1.0, 0)):
        _, _, covs = synthetic(sigma)
        out = bench.check_relations(stamps, p, covs, rel)
        s = out.summary
        assert (s.used, s.gross, s.confident_gross) == (4, 1, confident)
        assert s.median_d2 == pytest.approx(0.0, abs=1e-12)  # the others are exact
        assert s.within_999 == (0.75 if confident else 1.0)
        # the error is ⊖ref ⊕ est: the injected metre, reversed
        np.testing.assert_allclose(out.error[1], inverse([1.0, 0.0, 0.0]), atol=1e-9)


def test_a_rotation_beyond_five_degrees_is_gross_and_below_not(bench) -> None:
    stamps, p, covs = synthetic(1e-3)
    pairs = [(0, 2), (4, 6)]
    rel = relations_of(
        stamps, p, pairs, {0: np.array([0, 0, math.radians(5.5)]), 1: np.array([0, 0, 0.08])}
    )
    s = bench.check_relations(stamps, p, covs, rel).summary
    assert (s.gross, s.confident_gross) == (1, 1)  # 4.6° is not gross, though far outside Σ


def test_the_d2_is_the_mahalanobis_distance_under_the_composed_covariance(bench) -> None:
    stamps, p, covs = synthetic(0.05)
    e = np.array([0.03, -0.02, 0.01])
    rel = relations_of(stamps, p, [(2, 6), (6, 2)], {0: e, 1: e})
    out = bench.check_relations(stamps, p, covs, rel)
    steps = np.array([relative(p[k], p[k + 1]) for k in range(2, 6)])
    motion, sigma = compose_steps(steps, covs[3:7])
    err = relative(rel.motion[0], relative(p[2], p[6]))
    assert out.d2[0] == pytest.approx(err @ np.linalg.solve(sigma, err), rel=1e-9)
    # backwards along the file: the inverse chain's covariance
    sigma_b = inverse_covariance(motion, sigma)
    err_b = relative(rel.motion[1], relative(p[6], p[2]))
    assert out.d2[1] == pytest.approx(err_b @ np.linalg.solve(sigma_b, err_b), rel=1e-9)
    widened = sigma + np.diag(np.square(bench.REFERENCE_SIGMA))
    assert out.d2_widened[0] == pytest.approx(err @ np.linalg.solve(widened, err), rel=1e-9)


def test_the_relations_taken_are_short_in_time_or_in_scans(bench) -> None:
    stamps, p, covs = synthetic()
    stamps = stamps.copy()
    stamps[15:] += 20.0  # a 21 s gap between scans 14 and 15
    pairs = [(0, 10), (0, 11), (10, 16), (14, 15), (2, 29)]
    rel = relations_of(stamps, p, pairs)
    out = bench.check_relations(stamps, p, covs, rel)
    # (0, 11): 11 s and 11 scans; (10, 16): 6 scans though 26 s; (14, 15): 21 s but one scan
    assert out.used.tolist() == [True, False, True, True, False]
    assert out.summary.selected == 3


@pytest.mark.parametrize(("offset", "matched"), [(0.0, True), (0.0019, True), (0.0021, False)])
def test_the_ends_match_within_two_milliseconds(bench, offset, matched) -> None:
    stamps, p, covs = synthetic()
    rel = relations_of(stamps, p, [(3, 5), (7, 8)])
    shifted = Relations(rel.t1 + np.array([offset, 0.0]), rel.t2, rel.motion)
    s = bench.check_relations(stamps, p, covs, shifted).summary
    assert s.used == (2 if matched else 1)
    assert s.unmatched == (0 if matched else 1)


def write_run(folder: Path, stamps, p, covs, drop: int | None = None) -> None:
    """A results folder: trajectory.tum and covariance.csv, an extra column after the seven,
    the row of ``drop`` left out."""
    folder.mkdir(parents=True, exist_ok=True)
    write_tum(folder / "trajectory.tum", stamps, p)
    lines = ["stamp,xx,xy,xtheta,yy,ytheta,thetatheta,extra"]
    for k, (t, c) in enumerate(zip(stamps, covs)):
        if k == drop:
            continue
        vals = [c[0, 0], c[0, 1], c[0, 2], c[1, 1], c[1, 2], c[2, 2]]
        lines.append(",".join([repr(float(t)), *(repr(float(v)) for v in vals), "7"]))
    (folder / "covariance.csv").write_text("\n".join(lines) + "\n")


def test_a_missing_covariance_row_skips_the_relations_over_it(bench, tmp_path) -> None:
    stamps, p, covs = synthetic()
    covs[:, 0, 1] = covs[:, 1, 0] = 1e-6  # an off-diagonal entry, to read by name
    rel = relations_of(stamps, p, [(0, 3), (4, 8), (6, 7), (8, 9)], {3: np.array([1, 0, 0])})
    (tmp_path / "r.relations").write_text(
        "".join(
            f"{a!r} {b!r} {m[0]!r} {m[1]!r} 0 0 0 {m[2]!r}\n"
            for a, b, m in zip(rel.t1.tolist(), rel.t2.tolist(), rel.motion.tolist())
        )
    )
    write_run(tmp_path / "run", stamps, p, covs, drop=7)
    s = bench.check_run(tmp_path / "run", tmp_path / "r.relations")
    assert (s.used, s.no_covariance, s.gross) == (2, 2, 1)  # (4, 8) and (6, 7) span row 7
    read_stamps, read = bench.read_covariance(tmp_path / "run" / "covariance.csv")
    aligned = bench.align_covariances(stamps, read_stamps, read)
    assert np.isnan(aligned[7]).all()
    np.testing.assert_array_equal(np.delete(aligned, 7, axis=0), np.delete(covs, 7, axis=0))


def test_the_covariance_columns_are_read_by_name(bench, tmp_path) -> None:
    path = tmp_path / "covariance.csv"
    path.write_text("stamp,yy,xx,xy,xtheta,ytheta,thetatheta\n1.5,2,1,0.1,0.2,0.3,3\n")
    stamps, covs = bench.read_covariance(path)
    assert stamps.tolist() == [1.5]
    np.testing.assert_array_equal(covs[0], [[1, 0.1, 0.2], [0.1, 2, 0.3], [0.2, 0.3, 3]])
    path.write_text("stamp,xx,xy,xtheta,yy,ytheta\n1.5,1,0,0,1,0\n")
    with pytest.raises(ValueError, match="thetatheta"):
        bench.read_covariance(path)


def test_the_report_names_date_commit_machine_and_command(bench, tmp_path, capsys) -> None:
    stamps, p, covs = synthetic(1e-3)
    rel = relations_of(stamps, p, [(0, 3), (5, 9)], {1: np.array([1.0, 0.0, 0.0])})
    rel_path = tmp_path / "syn.relations"
    rel_path.write_text(
        "".join(
            f"{a!r} {b!r} {m[0]!r} {m[1]!r} 0 0 0 {m[2]!r}\n"
            for a, b, m in zip(rel.t1.tolist(), rel.t2.tolist(), rel.motion.tolist())
        )
    )
    write_run(tmp_path / "run", stamps, p, covs)
    out = tmp_path / "docs" / "honesty.md"
    bench.main([str(tmp_path / "run"), str(rel_path), "--out", str(out)])
    printed = capsys.readouterr().out
    assert "| syn | 2 | 1 | 1 |" in printed
    text = out.read_text()
    for word in ("date:", "commit:", "machine:", "command: `python benchmarks/bench_honesty.py"):
        assert word in text
    assert "| syn | 2 | 1 | 1 |" in text
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["rows"][0]["confident_gross"] == 1 and data["rows"][0]["used"] == 2


def test_a_results_folder_of_the_run_job_reads(bench, tmp_path) -> None:
    """``fuzzypos run``'s own results folder (covariance.csv as the run job writes it, with
    whatever columns follow the seven): every short relation used, none unmatched."""
    log = tmp_path / "sim.clf"
    sim_run = write_sim_log(log)
    run_log(open_log(log), results_dir=tmp_path / "out", plot=False)
    stamps, _ = read_tum(tmp_path / "out" / "trajectory.tum")
    pairs = [(k, k + 3) for k in range(0, len(stamps) - 3, 5)]
    write_relations(tmp_path / "sim.relations", stamps, np.array(sim_run.true_poses), pairs)
    s = bench.check_run(tmp_path / "out", tmp_path / "sim.relations")
    assert (s.relations, s.used, s.unmatched, s.no_covariance) == (len(pairs), len(pairs), 0, 0)
    assert math.isfinite(s.median_d2) and s.median_d2 > 0
    cov_stamps, covs = bench.read_covariance(tmp_path / "out" / "covariance.csv")
    np.testing.assert_array_equal(cov_stamps, stamps)
    assert np.all(np.linalg.eigvalsh(covs) > 0)


# -- the scans' word on the reference -----------------------------------------------------------
def _two_scans(turn_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two simulated scans in the furnished room, the second 0.4 m on and ``turn_deg`` turned,
    their points in the robot frame and the true motion between them."""
    from fuzzypos.geometry import Pose2D
    from fuzzypos.sim.scanner import ScannerModel, simulate_scan
    from fuzzypos.sim.worlds import furnished_room

    world, scanner = furnished_room(1), ScannerModel.sick_lms200()
    rng = np.random.default_rng(3)
    a, b = (
        Pose2D(0.0, 0.0, 0.2),
        Pose2D(0.0, 0.0, 0.2).compose(Pose2D(0.4, 0.05, math.radians(turn_deg))),
    )
    pts = []
    for pose in (a, b):
        xy = simulate_scan(world, pose, scanner, rng).points_robot()
        pts.append(xy[np.isfinite(xy).all(axis=1)])
    return pts[0], pts[1], relative(a.as_array(), b.as_array())


def test_the_true_motion_lays_the_scans_on_each_other(bench) -> None:
    """Most of the second scan lies within the radius of the first at the true motion; few at
    a motion 10° off."""
    first, second, truth = _two_scans(15.0)
    n_true = bench.agreement(first, second, truth, bench.ALIGN_RADIUS_M)
    off = truth + (0.0, 0.0, math.radians(10.0))
    n_off = bench.agreement(first, second, off, bench.ALIGN_RADIUS_M)
    assert n_true > 0.6 * second.shape[0]
    assert n_off < 0.3 * n_true


@pytest.mark.parametrize(
    ("reference_off", "estimate_off", "contradicted"),
    [
        ((0.0, 0.0, 10.0), (0.0, 0.0, 0.0), True),  # a reference 10° off, the estimate right
        ((0.4, 0.0, 0.0), (0.0, 0.0, 0.0), True),  # a reference 0.4 m off
        ((0.0, 0.0, 0.0), (0.0, 0.0, 10.0), False),  # the reference right, the estimate off
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), False),  # both right: no evidence either way
    ],
)
def test_the_scans_contradict_only_a_reference_that_misaligns_them(
    bench, reference_off, estimate_off, contradicted
) -> None:
    first, second, truth = _two_scans(15.0)
    ref = compose(
        truth, np.array([reference_off[0], reference_off[1], math.radians(reference_off[2])])
    )
    est = compose(
        truth, np.array([estimate_off[0], estimate_off[1], math.radians(estimate_off[2])])
    )
    assert bench.reference_contradicted(first, second, ref, est) is contradicted


def test_a_run_counts_the_references_its_scans_contradict(bench, tmp_path) -> None:
    """On a simulated run, relations whose motion is the truth turned by 20° are confident
    gross errors whose reference the log's scans contradict; with the log not given, nothing
    is checked."""
    log = tmp_path / "sim.clf"
    sim_run = write_sim_log(log)
    run_log(open_log(log), results_dir=tmp_path / "out", plot=False)
    stamps, _ = read_tum(tmp_path / "out" / "trajectory.tum")
    truth = np.array(sim_run.true_poses)
    pairs = [(k, k + 2) for k in range(0, len(stamps) - 2, 6)]
    wrong = truth.copy()
    for i, j in pairs[::2]:  # every other relation 20° off
        wrong[j] = compose(truth[i], compose(relative(truth[i], truth[j]), np.array([0, 0, 0.35])))
    write_relations(tmp_path / "sim.relations", stamps, wrong, pairs[::2])
    with_log = bench.check_run(tmp_path / "out", tmp_path / "sim.relations", log)
    assert with_log.confident_gross == len(pairs[::2])
    assert with_log.reference_contradicted == with_log.confident_gross
    assert with_log.confident_gross_sound == 0
    without = bench.check_run(tmp_path / "out", tmp_path / "sim.relations")
    assert without.reference_contradicted == -1 and without.confident_gross_sound == -1
