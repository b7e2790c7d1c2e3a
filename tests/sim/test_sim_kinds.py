"""Simulated runs of the kinds of real log we are checked on (``fuzzypos.sim.kinds``).

:func:`fuzzypos.sim.sick_outdoor_run` mimics a held-back CARMEN ROBOTLASER1 log: an interlaced
SICK at 1.6 Hz in a yard of far structure, 12% no-returns read as 81.83 m, the laser 0.22 m
ahead, odometry precise but under-reading rotation by 1%. First its parts (the interlaced
start angles, the no-return code and fraction, the mounting, the odometry's under-read), then
writing it as a CARMEN log, then the default positioner on it against odometry
(``python benchmarks/bench_sim_kinds.py`` prints the figures for three seeds).
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from fuzzypos import Config, Positioner, sim
from fuzzypos.eval import relative_pose_error
from fuzzypos.geometry import Pose2D
from fuzzypos.io import CarmenRecord, read_carmen, write_carmen
from fuzzypos.scan import LaserScan
from fuzzypos.sim import ScannerModel, SimError, World
from helpers import EXACT_SCANNER

OFFSETS = (0.0, 0.25, 0.5, 0.75)
EXACT = EXACT_SCANNER


def _bench() -> ModuleType:
    """``benchmarks/bench_sim_kinds.py``, whose figures the end-to-end tests compare."""
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_sim_kinds.py"
    spec = importlib.util.spec_from_file_location("bench_sim_kinds", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def run() -> sim.SimulatedRun:
    return sim.sick_outdoor_run(seed=0)


# -- the scanner: interlaced start angles, no-return code --------------------------------------
def test_the_start_angle_cycles_through_four_offsets_a_quarter_degree_apart(
    run: sim.SimulatedRun,
) -> None:
    assert len(run) == 311
    for k, scan in enumerate(run.scans[:12]):
        assert math.degrees(scan.angle_min) == pytest.approx(-90.0 + OFFSETS[k % 4], abs=1e-9)
        assert math.degrees(scan.angle_increment) == pytest.approx(1.0, abs=1e-12)
        assert scan.n_beams == (181 if k % 4 == 0 else 180)
        assert math.degrees(scan.angles[-1]) <= 90.0 + 1e-9
    # four consecutive scans together sample every 0.25° from -90° to +90°
    bearings = np.concatenate([s.angles for s in run.scans[:4]])
    quarter = np.round(np.degrees(bearings) * 4.0).astype(int)
    assert sorted(quarter.tolist()) == list(range(-360, 361))


def test_simulate_scans_and_a_lone_scan_use_the_index() -> None:
    scanner = sim.sick_interlaced_scanner(**EXACT)
    world = sim.outdoor_yard()
    scans = sim.simulate_scans(world, [Pose2D()] * 5, scanner)
    assert [round(math.degrees(s.angle_min), 6) for s in scans] == [-90, -89.75, -89.5, -89.25, -90]
    lone = sim.simulate_scan(world, Pose2D(), scanner, index=6)
    assert math.degrees(lone.angle_min) == pytest.approx(-89.5)
    np.testing.assert_array_equal(lone.ranges, scans[2].ranges)


def test_no_returns_are_twelve_percent_and_read_the_code(run: sim.SimulatedRun) -> None:
    ranges = np.concatenate([s.ranges for s in run.scans])
    code = ranges == sim.kinds.SICK_NO_RETURN
    p, n = 0.12, ranges.size
    assert abs(code.mean() - p) < 4.0 * math.sqrt(p * (1.0 - p) / n)  # binomial, 4 sigma
    # the code sits below the maximum range: a scan counts it as a valid reading
    assert run.scans[0].range_max == 81.9
    assert all(s.valid[s.ranges == 81.83].all() for s in run.scans[:20])
    # nothing else reads near the code or beyond 70 m: the yard is closed
    assert ranges[~code].max() < 70.0


def test_without_dropouts_the_closed_yard_has_no_no_returns() -> None:
    quiet = sim.sick_interlaced_scanner(dropout_probability=0.0)
    short = sim.sick_outdoor_run(seed=3, duration=10.0, scanner=quiet)
    assert not any((s.ranges == 81.83).any() for s in short.scans)


def test_a_beam_that_hits_nothing_reads_the_code_and_the_default_is_unchanged() -> None:
    wall = World.from_segments([[5.0, -1.0, 5.0, 1.0]])  # only the beams near 0° hit
    coded = sim.simulate_scan(wall, Pose2D(), sim.sick_interlaced_scanner(**EXACT))
    hit = coded.ranges < 10.0
    assert 0 < hit.sum() < 30
    assert (coded.ranges[~hit] == 81.83).all()
    plain = sim.simulate_scan(wall, Pose2D(), ScannerModel(range_max=81.9))
    assert (plain.ranges[plain.ranges > 10.0] == 81.9).all()
    assert not plain.valid[plain.ranges > 10.0].any()
    default = ScannerModel()
    assert not default.is_interlaced and default.no_return == default.range_max
    np.testing.assert_array_equal(default.angles(0), default.angles(3))


@pytest.mark.parametrize(
    "changes",
    [
        {"beam_counts": (181, 180)},  # not as many as the offsets
        {"beam_counts": (0, 180, 180, 180)},
        {"start_angle_offsets_deg": (0.0, math.nan, 0.5, 0.75)},
        {"no_return_value": 82.0},  # above range_max
        {"no_return_value": 0.0},  # at range_min
        {"no_return_value": True},
    ],
)
def test_bad_interlacing_or_code_is_refused(changes: dict[str, object]) -> None:
    with pytest.raises(SimError):
        sim.sick_interlaced_scanner(**changes)


def test_the_laser_sits_022_m_ahead_of_the_base(run: sim.SimulatedRun) -> None:
    assert all(s.sensor_pose == Pose2D(0.22, 0.0, 0.0) for s in run.scans)
    wall = World.from_segments([[5.0, -50.0, 5.0, 50.0]])
    scan = sim.simulate_scan(wall, Pose2D(), sim.sick_interlaced_scanner(**EXACT))
    ahead = int(np.argmin(np.abs(scan.angles)))
    assert scan.angles[ahead] == pytest.approx(0.0, abs=1e-12)
    assert scan.ranges[ahead] == pytest.approx(5.0 - 0.22, abs=1e-9)
    # the returns put into the robot frame land on the wall
    pts = scan.points_robot()[scan.ranges < 81.0]
    assert len(pts) > 100
    assert np.abs(pts[:, 0] - 5.0).max() < 1e-9


# -- the odometry and the path ----------------------------------------------------------------
def test_the_odometry_under_reads_rotation_by_one_percent(run: sim.SimulatedRun) -> None:
    true_inc, odo_inc = run.true_increments, run.odometry_increments
    turning = np.abs(true_inc[:, 2]) > math.radians(0.5)
    ratio = np.sum(odo_inc[turning, 2] * np.sign(true_inc[turning, 2])) / np.sum(
        np.abs(true_inc[turning, 2])
    )
    assert ratio == pytest.approx(0.99, abs=0.002)
    # translation is read right (within the encoder noise)
    dist = np.hypot(true_inc[:, 0], true_inc[:, 1]).sum()
    assert np.hypot(odo_inc[:, 0], odo_inc[:, 1]).sum() == pytest.approx(dist, rel=0.002)


def test_the_path_keeps_025_m_between_scans_and_far_from_structure(
    run: sim.SimulatedRun,
) -> None:
    step = np.hypot(run.true_increments[:, 0], run.true_increments[:, 1])
    assert step.min() >= 0.2 and step.max() <= 0.3
    assert run.stamps[1] == pytest.approx(1.0 / 1.6)
    assert math.degrees(np.abs(run.true_increments[:, 2]).max()) < 4.0
    assert run.world.distance(run.true_poses[:, :2]).min() > 9.0
    hits = np.concatenate([s.ranges[s.ranges != 81.83] for s in run.scans])
    assert 10.0 < np.median(hits) < 50.0


# -- as a CARMEN log -----------------------------------------------------------------------
def _robotlaser1(scan: LaserScan, odometry: Pose2D) -> str:
    """A ROBOTLASER1 line for a scan, no remissions (as CARMEN's logger writes it; fuzzypos
    has no ROBOTLASER1 writer)."""
    laser = odometry.compose(scan.sensor_pose)
    fov = scan.angle_increment * (scan.n_beams - 1)
    head = [scan.angle_min, fov, scan.angle_increment, scan.range_max]
    tail = [laser.x, laser.y, laser.theta, odometry.x, odometry.y, odometry.theta, 0, 0, 0, 0, 0]
    text = [repr(float(v)) for v in head]
    body = " ".join(repr(float(r)) for r in scan.ranges)
    rest = " ".join(repr(float(v)) for v in tail)
    return (
        f"ROBOTLASER1 0 {' '.join(text)} 0.01 0 {scan.n_beams} {body} 0 {rest} "
        f"{scan.stamp!r} sim {scan.stamp!r}\n"
    )


def test_robotlaser1_lines_of_the_run_read_back(run: sim.SimulatedRun, tmp_path: Path) -> None:
    path = tmp_path / "sick.clf"
    n = 8
    path.write_text("".join(_robotlaser1(run.scans[k], run.odometry_pose(k)) for k in range(n)))
    records = list(read_carmen(path))
    assert len(records) == n
    for k, rec in enumerate(records):
        orig = run.scans[k]
        assert rec.scan.n_beams == orig.n_beams
        assert rec.scan.angle_min == pytest.approx(orig.angle_min, abs=1e-12)
        assert rec.scan.angle_increment == pytest.approx(orig.angle_increment, abs=1e-12)
        np.testing.assert_array_equal(rec.scan.ranges, orig.ranges)
        assert rec.scan.range_max == 81.9
        sp = rec.scan.sensor_pose
        assert (sp.x, sp.y, sp.theta) == pytest.approx((0.22, 0.0, 0.0), abs=1e-9)
        assert rec.odometry is not None
        assert rec.odometry.as_array() == pytest.approx(run.odometry_poses[k], abs=1e-12)


def test_write_carmen_cannot_write_interlaced_scans_but_writes_the_unshifted_ones(
    run: sim.SimulatedRun, tmp_path: Path
) -> None:
    records = [
        CarmenRecord(s, run.odometry_pose(k), run.true_pose(k)) for k, s in enumerate(run.scans)
    ]
    bad = tmp_path / "interlaced.clf"
    with pytest.raises(ValueError, match="does not fit FLASER"):
        write_carmen(bad, records[:2])  # the second starts at -89.75°
    assert not bad.exists()
    good = tmp_path / "unshifted.clf"
    assert write_carmen(good, records[::4]) == len(records[::4])  # every 4th: -90°, 181 beams
    back = list(read_carmen(good))
    assert len(back) == len(records[::4])
    for rec, orig in zip(back, records[::4]):
        assert rec.scan.n_beams == 181
        assert rec.scan.angle_min == pytest.approx(-math.pi / 2, abs=1e-12)
        assert rec.scan.range_max == 81.9
        np.testing.assert_allclose(rec.scan.ranges, orig.scan.ranges, atol=5.1e-5)
        assert rec.scan.sensor_pose == Pose2D(0.22, 0.0, 0.0)
        assert rec.truth is not None and orig.truth is not None
        assert rec.truth.as_array() == pytest.approx(orig.truth.as_array(), abs=1e-12)


# -- the default positioner against odometry ------------------------------------------------
#: "no worse than odometry locally": the default's mean local errors may exceed odometry's by
#: this much (m, degrees) over 2 and 5 scans (1.25 s and 3.1 s)
LOCAL_TOL_M = 0.003
LOCAL_TOL_DEG = 0.03


@pytest.fixture(scope="module")
def positioner(run: sim.SimulatedRun) -> tuple[Positioner, np.ndarray]:
    """The default positioner after the run, and its poses."""
    pos = Positioner()
    return pos, _bench().estimate(run, pos)


@pytest.fixture(scope="module")
def figures(run: sim.SimulatedRun, positioner: tuple[Positioner, np.ndarray]) -> tuple[Any, Any]:
    bench = _bench()
    return bench.figures(run, run.odometry_poses), bench.figures(run, positioner[1])


def test_the_default_beats_odometry_over_the_whole_run(figures: tuple[Any, Any]) -> None:
    odo, default = figures
    assert default.final_position_m < odo.final_position_m
    assert default.mean_position_m < 0.5 * odo.mean_position_m


def test_the_default_is_no_worse_than_odometry_locally(figures: tuple[Any, Any]) -> None:
    odo, default = figures
    for w in (2, 5):
        assert default.local_translation_m[w] <= odo.local_translation_m[w] + LOCAL_TOL_M, (
            f"translation over {w} scans"
        )
        assert default.local_rotation_deg[w] <= odo.local_rotation_deg[w] + LOCAL_TOL_DEG, (
            f"rotation over {w} scans"
        )


def test_once_learned_the_odometry_is_trusted_and_calibrated(
    run: sim.SimulatedRun, positioner: tuple[Positioner, np.ndarray]
) -> None:
    """The odometry here is more precise than the matches: once its noise is learned it is
    the refinement's prior (``trust_where_better``), its 1% rotation under-read calibrated
    away, and from then on the increments are as precise as the odometry's, not the scans'."""
    pos, poses = positioner
    noise = pos.odometry_noise
    assert noise.better_than_matching and noise.trusted
    assert noise.rotation_factor == pytest.approx(1.0 / 0.99, abs=0.005)
    assert noise.scale == pytest.approx(1.0, abs=0.005)
    learned = slice(80, None)  # the noise is learned from 30 matches, then trusted
    stamps, truth = run.stamps[learned], run.true_poses[learned]
    est = relative_pose_error(stamps, truth, stamps, poses[learned], delta=2)
    odo = relative_pose_error(stamps, truth, stamps, run.odometry_poses[learned], delta=2)
    assert est.translation_m.mean <= odo.translation_m.mean + 0.001
    assert est.rotation_deg.mean <= odo.rotation_deg.mean
    # not trusting it, the increments keep the scans' centimetre
    plain = Positioner(Config().with_overrides({"odometry_noise": {"trust_where_better": False}}))
    untrusted = _bench().estimate(run, plain)[learned]
    alone = relative_pose_error(stamps, truth, stamps, untrusted, delta=2)
    assert alone.translation_m.mean > 3.0 * odo.translation_m.mean
