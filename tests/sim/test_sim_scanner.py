"""Tests of the scanner's error model: σ(ρ, β) range noise, dropouts, spurious returns, the
SICK LMS200 preset and the scan rate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from fuzzypos import sim
from fuzzypos.geometry import Pose2D
from fuzzypos.sim import ScannerModel, SimError, World, rectangular_room, simulate_scan
from helpers import EXACT_SCANNER

EXACT = EXACT_SCANNER


def tilted_wall(d: float, psi: float, half: float = 100.0) -> World:
    """The wall ``n·p = d`` with normal ``n = (cos psi, sin psi)``, ``2 * half`` long."""
    n = np.array([math.cos(psi), math.sin(psi)])
    t = np.array([-n[1], n[0]])
    a, b = d * n - half * t, d * n + half * t
    return World.from_segments([[a[0], a[1], b[0], b[1]]])


def wall_truth(scanner: ScannerModel, d: float, psi: float) -> tuple[np.ndarray, np.ndarray]:
    """True range and detection angle β (radians) of every beam of a scanner at the origin
    facing +x, for the wall of :func:`tilted_wall` (NaN where the beam does not meet it)."""
    c = np.cos(scanner.angles() - psi)
    with np.errstate(divide="ignore"):
        rho = np.where(c > 1e-9, d / c, np.nan)
    beta = np.arcsin(np.clip(np.abs(c), 0.0, 1.0))  # sin β = |cos(beam - normal)|
    return rho, beta


# ---------------------------------------------------------------------------------------------
# the model's parameters
# ---------------------------------------------------------------------------------------------


def test_defaults_are_an_exact_scanner_at_ten_hertz() -> None:
    s = ScannerModel()
    assert (s.range_noise_std, s.range_noise_per_metre, s.incidence_noise) == (0.0, 0.0, 0.0)
    assert (s.dropout_probability, s.spurious_probability) == (0.0, 0.0)
    assert s.rate_hz == 10.0 and s.scan_period == pytest.approx(0.1)
    assert not s.is_noisy
    # existing positional use keeps working: the new fields come after sensor_pose
    s = ScannerModel(90, 180.0, -90.0, 6.0, 0.1, 0.01, Pose2D(0.1, 0.0, 0.0))
    assert s.n_beams == 90 and s.range_noise_std == 0.01 and s.sensor_pose.x == 0.1


def test_sick_lms200_preset() -> None:
    s = ScannerModel.sick_lms200()
    assert (s.n_beams, s.field_of_view_deg, s.angle_min_deg) == (180, 180.0, -90.0)
    assert s.angle_increment == pytest.approx(math.radians(1.0))
    assert (s.range_min, s.range_max, s.rate_hz) == (0.02, 8.0, 10.0)
    assert (s.range_noise_std, s.range_noise_per_metre, s.incidence_noise) == (0.01, 0.005, 0.02)
    assert (s.dropout_probability, s.spurious_probability) == (0.01, 0.002)
    assert s.is_noisy and s.has_range_noise and s.has_outliers
    # σ: 1 cm near the scanner square-on, 5 cm at 8 m, 2 cm more at grazing incidence
    np.testing.assert_allclose(
        s.range_std(
            [0.0, 4.0, 8.0, 4.0, 4.0], [math.pi / 2, math.pi / 2, math.pi / 2, 0.0, math.pi / 6]
        ),
        [0.01, 0.03, 0.05, 0.05, 0.04],
        rtol=0,
        atol=1e-15,
    )
    # overrides, and replace()
    assert ScannerModel.sick_lms200(range_max=20.0).range_max == 20.0
    assert s.replace(rate_hz=5.0).scan_period == pytest.approx(0.2)
    with pytest.raises(SimError):
        ScannerModel.sick_lms200(dropout_probability=2.0)


@pytest.mark.parametrize(
    "kw",
    [
        {"range_noise_per_metre": -0.001},
        {"incidence_noise": -0.01},
        {"dropout_probability": -0.1},
        {"dropout_probability": 1.5},
        {"spurious_probability": 1.01},
        {"dropout_probability": 0.6, "spurious_probability": 0.5},
        {"rate_hz": 0.0},
        {"rate_hz": -10.0},
        {"rate_hz": math.inf},
        {"incidence_noise": math.nan},
        {"dropout_probability": True},
    ],
)
def test_new_fields_are_validated(kw: dict) -> None:
    with pytest.raises(SimError):
        ScannerModel(**kw)


# ---------------------------------------------------------------------------------------------
# ranges
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("psi_deg", [0.0, 25.0, -50.0])
def test_range_to_a_tilted_wall_is_exact_with_the_noise_off(psi_deg: float) -> None:
    d, psi = 3.0, math.radians(psi_deg)
    scanner = ScannerModel.sick_lms200(**EXACT)
    rho, _ = wall_truth(scanner, d, psi)
    scan = simulate_scan(tilted_wall(d, psi), Pose2D(), scanner)
    seen = np.isfinite(rho) & (rho < scanner.range_max - 1e-6)
    assert seen.sum() > 60
    np.testing.assert_allclose(scan.ranges[seen], rho[seen], rtol=0, atol=1e-9)
    assert np.all(scan.ranges[~seen] == scanner.range_max)
    # the same with a generator passed: no noise term means no draws and no change
    rng = np.random.default_rng(0)
    again = simulate_scan(tilted_wall(d, psi), Pose2D(), scanner, rng)
    np.testing.assert_array_equal(again.ranges, scan.ranges)
    assert rng.random() == np.random.default_rng(0).random()


def test_range_noise_std_alone_draws_as_before() -> None:
    """With only ``range_noise_std`` set, the scans are bit for bit those of the earlier
    simulator: one N(0, σ) draw per beam, added to hits and clipped."""
    world = sim.furnished_room(0)
    plain = ScannerModel(range_min=0.5)
    noisy = ScannerModel(range_min=0.5, range_noise_std=0.03)
    pose = Pose2D(0.3, 0.2, 0.5)
    truth = simulate_scan(world, pose, plain).ranges
    got = simulate_scan(world, pose, noisy, np.random.default_rng(3)).ranges
    noise = np.random.default_rng(3).normal(0.0, 0.03, size=noisy.n_beams)
    hit = (truth < plain.range_max) & (truth >= plain.range_min)
    want = np.where(hit, np.clip(truth + noise, 0.5, plain.range_max), truth)
    np.testing.assert_array_equal(got, want)


def test_noise_follows_sigma_of_distance_and_detection_angle() -> None:
    """Over many scans of a tilted wall the errors are zero-mean with std σ(ρ, β) beam by beam:
    pooled, and in groups of near-square, oblique and grazing beams."""
    d, psi = 2.5, math.radians(35.0)
    scanner = ScannerModel.sick_lms200(
        range_noise_std=0.01,
        range_noise_per_metre=0.01,
        incidence_noise=0.05,
        dropout_probability=0.0,
        spurious_probability=0.0,
        range_max=20.0,
    )
    rho, beta = wall_truth(scanner, d, psi)
    use = np.isfinite(rho) & (rho < 12.0)  # far from range_max: no clipping
    sigma = scanner.range_std(rho[use], beta[use])
    world = tilted_wall(d, psi)
    rng = np.random.default_rng(2024)
    n_scans = 300
    err = np.array(
        [
            simulate_scan(world, Pose2D(), scanner, rng).ranges[use] - rho[use]
            for _ in range(n_scans)
        ]
    )
    z = err / sigma  # (n_scans, beams), N(0, 1) if σ(ρ, β) is right
    n = z.size
    assert abs(z.mean()) < 5.0 / math.sqrt(n)
    assert abs(z.std(ddof=1) - 1.0) < 5.0 / math.sqrt(2.0 * (n - 1))
    b = np.degrees(beta[use])
    for lo, hi in [(70.0, 90.1), (35.0, 70.0), (0.0, 35.0)]:
        g = z[:, (b >= lo) & (b < hi)]
        assert g.shape[1] >= 5, (lo, hi)
        m = g.size
        assert abs(g.mean()) < 5.0 / math.sqrt(m)
        assert abs(g.std(ddof=1) - 1.0) < 5.0 / math.sqrt(2.0 * (m - 1)), (lo, hi, g.std())
    # and σ itself spans a range: grazing beams are several times noisier than square-on ones
    assert sigma.max() > 3.0 * sigma.min()


def test_dropouts_and_spurious_returns_at_their_rates() -> None:
    p_drop, p_spur = 0.05, 0.03
    world = rectangular_room(8.0, 6.0)
    base = {"n_beams": 360, "field_of_view_deg": 360.0, "angle_min_deg": -180.0, "range_max": 50.0}
    clean = ScannerModel(**base)
    scanner = ScannerModel(
        **base, range_min=0.1, dropout_probability=p_drop, spurious_probability=p_spur
    )
    pose = Pose2D(0.7, -0.4, 0.3)
    truth = simulate_scan(world, pose, clean).ranges
    assert np.all(truth < 50.0)  # every beam hits a wall
    rng = np.random.default_rng(99)
    ranges = np.array([simulate_scan(world, pose, scanner, rng).ranges for _ in range(200)])
    n = ranges.size
    dropped = ranges == 50.0
    short = ranges < truth - 1e-9
    assert not (dropped & short).any()
    assert np.all((ranges == truth) | dropped | short)  # nothing else changes
    for count, p in [(dropped.sum(), p_drop), (short.sum(), p_spur)]:
        assert abs(count / n - p) < 5.0 * math.sqrt(p * (1.0 - p) / n)
    # a spurious return is uniform between range_min and the true range
    t = np.broadcast_to(truth, ranges.shape)[short]
    u = (ranges[short] - 0.1) / (t - 0.1)
    assert stats.kstest(u, "uniform").pvalue > 1e-3
    assert np.all(ranges[short] >= 0.1)


def test_outliers_on_beams_with_no_return() -> None:
    """A beam with no return stays at range_max when it drops out; a spurious return on it is
    uniform in [range_min, range_max)."""
    scanner = ScannerModel(range_max=5.0, range_min=0.2, spurious_probability=0.5)
    empty = World.from_segments(np.empty((0, 4)))
    rng = np.random.default_rng(1)
    r = np.array([simulate_scan(empty, Pose2D(), scanner, rng).ranges for _ in range(100)])
    spur = r < 5.0
    assert abs(spur.mean() - 0.5) < 5.0 * math.sqrt(0.25 / r.size)
    assert r[spur].min() >= 0.2 and r[spur].max() < 5.0
    assert stats.kstest((r[spur] - 0.2) / 4.8, "uniform").pvalue > 1e-3
    dropping = ScannerModel(range_max=5.0, dropout_probability=1.0)
    assert np.all(simulate_scan(rectangular_room(), Pose2D(), dropping, rng).ranges == 5.0)


def test_noisy_scans_are_reproducible_and_use_a_fixed_number_of_draws() -> None:
    scanner = ScannerModel.sick_lms200()
    world = sim.gym()
    pose = Pose2D(4.0, 0.0, math.pi / 2)
    a = simulate_scan(world, pose, scanner, np.random.default_rng(5))
    b = simulate_scan(world, pose, scanner, np.random.default_rng(5))
    np.testing.assert_array_equal(a.ranges, b.ranges)
    # n normals then 2n uniforms per scan, whatever the beams hit
    rng = np.random.default_rng(5)
    simulate_scan(sim.rectangular_room(), pose, scanner, rng)
    ref = np.random.default_rng(5)
    ref.standard_normal(scanner.n_beams)
    ref.random(2 * scanner.n_beams)
    assert rng.random() == ref.random()
    # simulate_scans makes its own generator when the scanner is noisy
    scans = sim.simulate_scans(world, [pose, pose], ScannerModel(dropout_probability=0.5))
    assert not np.array_equal(scans[0].ranges, scans[1].ranges)
