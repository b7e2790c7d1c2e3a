"""The run's outputs say why (issue 34 item 8): ``covariance.csv``'s columns after the step's
covariance (the pose's covariance in the trajectory frame, the reason, degraded) and
``summary.json``'s ``reasons`` and ``odometry_noise``, in whole and partial runs."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import fuzzypos.jobs.run as run_module
from fuzzypos.config import Config
from fuzzypos.geometry import Pose2D, covariance_to_parent, propagate
from fuzzypos.io import CarmenRecord, open_log, read_tum, write_carmen
from fuzzypos.jobs import partial_results, run_log
from fuzzypos.jobs.outputs import (
    COVARIANCE_COLUMNS,
    POSE_COVARIANCE_COLUMNS,
    STEP_COVARIANCE_COLUMNS,
)
from fuzzypos.jobs.sinks import CovarianceSink, PoseCovariances, ScanResult
from fuzzypos.pipeline import Estimate, OdometryNoise, Positioner, Reason
from helpers import write_sim_log

LEGACY = ["stamp", "xx", "xy", "xtheta", "yy", "ytheta", "thetatheta"]
POSE = ["pose_xx", "pose_xy", "pose_xtheta", "pose_yy", "pose_ytheta", "pose_thetatheta"]
_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _upper(c: np.ndarray) -> list[float]:
    return [float(c[i, j]) for i, j in _UPPER]


def _full(u: list[float]) -> np.ndarray:
    xx, xy, xt, yy, yt, tt = u
    return np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]])


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def _recording(change=None):
    """A Positioner recording its estimates (``change(k, est)`` may replace each) and itself."""

    class Recording(Positioner):
        estimates: ClassVar[list[Estimate]] = []
        last: ClassVar[list[Positioner]] = []

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self.last.append(self)

        def update(self, scan, odom=None):
            est = super().update(scan, odom)
            if change is not None:
                est = change(len(self.estimates), est)
            self.estimates.append(est)
            return est

    return Recording


def _run_with(cls, log: Path, out: Path, **kw: Any):
    """``run_log`` with ``cls`` as the run job's Positioner."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_module, "Positioner", cls)
        return run_log(open_log(log), results_dir=out, plot=False, **kw)


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("reasons") / "sim.clf"
    run = write_sim_log(path)
    return path, run


@pytest.fixture(scope="module")
def varied_log(tmp_path_factory, sim_log):
    """The simulated log with a scan that stands still (the odometry of the scan before) and
    one that sees nothing (every reading invalid): four reasons in one run."""
    _, run = sim_log
    records = []
    for k, scan in enumerate(run.scans):
        odom, truth = run.odometry_pose(k), run.true_pose(k)
        if k == 12:
            scan = dataclasses.replace(scan, ranges=np.full(scan.ranges.shape, np.inf))
        records.append(CarmenRecord(scan, odom, truth))
        if k == 6:  # a scan between 6 and 7 where the odometry did not move
            half = 0.5 * (scan.stamp + run.scans[7].stamp)
            records.append(CarmenRecord(dataclasses.replace(scan, stamp=half), odom, truth))
    path = tmp_path_factory.mktemp("varied") / "varied.clf"
    write_carmen(path, records)
    return path


# -- covariance.csv ----------------------------------------------------------------------------
def test_the_header_keeps_the_step_columns_first_then_the_new_ones(sim_log, tmp_path):
    path, run = sim_log
    res = run_log(open_log(path), results_dir=tmp_path / "res", plot=False)
    header, rows = _rows(tmp_path / "res" / "covariance.csv")
    assert list(STEP_COVARIANCE_COLUMNS) == LEGACY and list(POSE_COVARIANCE_COLUMNS) == POSE
    assert header == list(COVARIANCE_COLUMNS) == [*LEGACY, *POSE, "reason", "degraded"]
    assert len(rows) == res.scans == len(run.scans)
    assert all(len(r) == len(header) == 15 for r in rows)
    assert [float(r[0]) for r in rows] == read_tum(tmp_path / "res" / "trajectory.tum")[0].tolist()
    assert {r[-1] for r in rows} <= {"0", "1"}


def test_an_old_reader_of_the_first_seven_columns_still_works(varied_log, tmp_path):
    """What read the file before the new columns (the first seven by position or by name)
    reads the same numbers from it."""
    rec = _recording()
    out = tmp_path / "res"
    _run_with(rec, varied_log, out)
    text = (out / "covariance.csv").read_text(encoding="utf-8")
    lines = text.splitlines()
    assert lines[0].split(",")[:7] == LEGACY
    by_split = np.array([[float(v) for v in ln.split(",")[:7]] for ln in lines[1:]])
    by_numpy = np.loadtxt(out / "covariance.csv", delimiter=",", skiprows=1, usecols=range(7))
    with open(out / "covariance.csv", newline="", encoding="utf-8") as f:
        by_name = np.array([[float(r[c]) for c in LEGACY] for r in csv.DictReader(f)])
    want = np.array(
        [[e.stamp, *_upper(np.asarray(e.covariance))] for e in rec.estimates], dtype=float
    )
    for got in (by_split, by_numpy, by_name):
        np.testing.assert_array_equal(got, want)


def test_the_pose_covariance_is_the_steps_propagated_in_the_trajectory_frame(sim_log, tmp_path):
    """On a simulated run: the first pose's covariance is the first step's, then each is
    ``propagate`` of the one before with the step, turned into the trajectory frame by the
    pose's heading (``covariance_to_parent``), as the bag has it."""
    path, _ = sim_log
    rec = _recording()
    out = tmp_path / "res"
    _run_with(rec, path, out)
    _header, rows = _rows(out / "covariance.csv")
    assert len(rows) == len(rec.estimates) > 20
    cov = None
    for k, (row, est) in enumerate(zip(rows, rec.estimates, strict=True)):
        step = np.asarray(est.covariance)
        assert [float(v) for v in row[1:7]] == _upper(step)
        cov = step if k == 0 else propagate(cov, est.increment.as_array(), step)
        want = _upper(covariance_to_parent(est.pose.as_array(), cov))
        got = [float(v) for v in row[7:13]]
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * max(map(abs, want)))
    # it grows along the run, as carrying a step's error forward must make it
    first, last = (_full([float(v) for v in r[7:13]]) for r in (rows[0], rows[-1]))
    assert np.trace(last[:2, :2]) > 10 * np.trace(first[:2, :2])
    assert np.all(np.linalg.eigvalsh(last) > 0)


def test_the_pose_covariance_on_known_estimates(tmp_path):
    """Estimates built by hand: the first pose (heading 90°) has the first step's covariance
    with x and y swapped in the trajectory frame; one metre ahead (along the trajectory's +y)
    the heading's variance adds 1 m² · σθ² across (x), x and θ correlating negatively."""
    c0, step = np.diag([4e-6, 1e-6, 1e-8]), np.diag([1e-6, 1e-6, 1e-8])
    ident = Pose2D()
    ests = [
        Estimate(0.0, Pose2D(0, 0, math.pi / 2), ident, ident, 0, False, covariance=c0,
                 reason=Reason.FIRST_SCAN),
        Estimate(0.5, Pose2D(0, 1, math.pi / 2), Pose2D(1, 0, 0), ident, 3, False,
                 covariance=step),
        Estimate(0.6, Pose2D(0, 1, math.pi / 2), ident, ident, 0, True, covariance=step,
                 reason=Reason.TOO_FEW_PAIRS),
    ]  # fmt: skip
    covariances, csv = PoseCovariances("hand"), CovarianceSink(tmp_path, "hand", required=False)
    csv.open()
    for k, est in enumerate(ests):
        csv.write(ScanResult(k, None, est, covariances.of(k, est)))
    assert csv.close(partial=False) == {"covariance.csv": tmp_path / "covariance.csv"}
    _header, rows = _rows(tmp_path / "covariance.csv")
    pose = [_full([float(v) for v in r[7:13]]) for r in rows]
    np.testing.assert_allclose(pose[0], np.diag([1e-6, 4e-6, 1e-8]), rtol=1e-12, atol=1e-20)
    one_metre = np.array([[1e-6 + 1e-8 + 1e-6, 0, -1e-8], [0, 4e-6 + 1e-6, 0], [-1e-8, 0, 2e-8]])
    np.testing.assert_allclose(pose[1], one_metre, rtol=1e-9, atol=1e-20)
    # standing on the spot: the step's covariance adds (turned by 90°: x and y alike here)
    np.testing.assert_allclose(pose[2], one_metre + step, rtol=1e-9, atol=1e-20)
    assert [(r[13], r[14]) for r in rows] == [
        ("first scan", "0"),
        ("matched", "0"),
        ("too few pairs", "1"),
    ]


def test_the_reasons_column_is_the_estimates(varied_log, tmp_path):
    rec = _recording()
    out = tmp_path / "res"
    res = _run_with(rec, varied_log, out)
    _header, rows = _rows(out / "covariance.csv")
    assert [r[13] for r in rows] == [e.reason.value for e in rec.estimates]
    assert [r[14] for r in rows] == [str(int(e.degraded)) for e in rec.estimates]
    seen = {r[13] for r in rows}
    assert seen >= {"first scan", "matched", "standing still", "too few features"}, seen
    assert res.summary["reasons"] == dict(Counter(r[13] for r in rows))
    assert sum(r[14] == "1" for r in rows) == res.scans_degraded >= 1


def test_a_reason_with_a_comma_is_quoted(sim_log, tmp_path):
    """A reason is one CSV field whatever it holds: one with a comma reads back whole."""
    path, _ = sim_log

    def odd(k: int, est: Estimate) -> Estimate:
        return dataclasses.replace(est, reason="odd, but a reason") if k == 3 else est

    out = tmp_path / "res"
    res = _run_with(_recording(odd), path, out)
    _header, rows = _rows(out / "covariance.csv")
    assert rows[3][13] == "odd, but a reason" and all(len(r) == 15 for r in rows)
    assert '"odd, but a reason"' in (out / "covariance.csv").read_text(encoding="utf-8")
    assert res.summary["reasons"]["odd, but a reason"] == 1


# -- summary.json --------------------------------------------------------------------------
def test_summary_counts_every_reason_and_they_sum_to_the_scans(varied_log, tmp_path):
    rec = _recording()
    out = tmp_path / "res"
    res = _run_with(rec, varied_log, out)
    s = json.loads((out / "summary.json").read_text())
    want = Counter(e.reason.value for e in rec.estimates)
    assert s["reasons"] == dict(want) and sum(s["reasons"].values()) == s["scans"] == res.scans
    # in the enum's order, only the reasons that occurred
    assert list(s["reasons"]) == [r.value for r in Reason if r.value in want]
    assert s["reasons"]["first scan"] == 1 and s["reasons"]["too few features"] >= 1


def test_summary_has_the_odometry_noise_learned_by_the_end(sim_log, tmp_path):
    path, _ = sim_log
    rec = _recording()
    out = tmp_path / "res"
    _run_with(rec, path, out)
    s = json.loads((out / "summary.json").read_text())
    noise = rec.last[-1].odometry_noise
    assert s["odometry_noise"] == noise.as_dict()
    assert s["odometry_noise"]["samples"] > 0  # the run's matches taught it
    cfg = Config().odometry_noise
    fresh = OdometryNoise(cfg).as_dict()
    assert fresh["samples"] == 0 and fresh["warm"] is (not cfg.learn)


def test_odometry_noise_as_dict_is_what_it_exposes():
    cfg = Config().odometry_noise
    noise = OdometryNoise(dataclasses.replace(cfg, min_samples=3, calibrate=True))
    d = noise.as_dict()
    assert set(d) == {
        "translation_per_sqrt_m", "rotation_per_sqrt_m", "stale_speed", "stale_turn_rate",
        "samples", "stale_samples", "warm", "better_than_matching", "trusted", "calibrated",
        "scale", "rotation_factor",
    }  # fmt: skip
    assert d["translation_per_sqrt_m"] == cfg.translation_per_sqrt_m and d["samples"] == 0
    assert d["warm"] is False and d["calibrated"] is True and d["scale"] == 1.0
    json.dumps(d)  # plain values
    for _ in range(3):  # the matches travel 2 % farther and turn 5 % more than the odometry says
        noise.learn(np.array([0.5, 0.0, 0.1]), np.array([0.51, 0.002, 0.105]))
    d = noise.as_dict()
    assert d["samples"] == 3 and d["warm"] is True
    assert d["scale"] == pytest.approx(noise.scale) == pytest.approx(1.02, rel=1e-3)
    assert d["rotation_factor"] == noise.rotation_factor == pytest.approx(1.05)
    assert d["translation_per_sqrt_m"] == noise.alpha_translation
    assert (d["trusted"], d["better_than_matching"]) == (noise.trusted, noise.better_than_matching)
    assert all(type(v) in (int, float, bool) for v in d.values())


# -- a partial run -----------------------------------------------------------------------------
def test_a_partial_run_keeps_the_new_columns_and_counts(sim_log, tmp_path):
    path, _ = sim_log
    rec = _recording()
    out = tmp_path / "res"

    def stop(done: int, total: int | None) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as info:
        _run_with(rec, path, out, progress=stop)
    kept = partial_results(info.value)
    assert kept is not None and kept.scans == 25
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] is True and sum(s["reasons"].values()) == 25
    assert s["reasons"] == dict(Counter(e.reason.value for e in rec.estimates[:25]))
    assert s["odometry_noise"] == rec.last[-1].odometry_noise.as_dict()
    header, rows = _rows(out / "covariance.csv")
    assert header == list(COVARIANCE_COLUMNS) and len(rows) == 25
    assert [r[13] for r in rows] == [e.reason.value for e in rec.estimates[:25]]
