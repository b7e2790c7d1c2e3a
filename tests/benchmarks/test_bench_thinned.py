"""The thinned logs of ``benchmarks/thinning.py`` (``bench_thinned.py`` and ``bench_peers.py``
run them): which scans the rule keeps on known odometry, and the thinned CARMEN logs (FLASER
and ROBOTLASER1) reading back as the scans kept."""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from fuzzypos import LaserScan, Pose2D
from fuzzypos.io import LogRecord, open_log, write_carmen
from helpers import load_benchmark


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("thinning")


def path_odometry() -> list[tuple[float, float, float] | None]:
    """0.125 m straight steps for 12 scans (0 … 11), then turning in place 6° a scan for 9
    (12 … 20, to 54°), then one scan without odometry (21), then 0.15 m steps at 54° from
    the turn's position (22 … 29). No distance or angle lands on a threshold."""
    odo: list[tuple[float, float, float] | None] = [(0.125 * k, 0.0, 0.0) for k in range(12)]
    x = 0.125 * 11
    odo += [(x, 0.0, math.radians(6.0 * (k - 11))) for k in range(12, 21)]
    odo.append(None)
    th = math.radians(54.0)
    odo += [
        (x + 0.15 * (k - 21) * math.cos(th), 0.15 * (k - 21) * math.sin(th), th)
        for k in range(22, 30)
    ]
    return odo


STAMPS = [10.0 + 0.5 * k for k in range(30)]


def test_the_rule_keeps_a_scan_every_half_metre_or_ten_degrees(bench) -> None:
    kept = bench.thin_indices(STAMPS, path_odometry(), np.array([]), 0.5, 10.0)
    # 0.5 m = 4 steps: 0, 4, 8; the turn, 0.375 m from 8: 12° at 13, then every 2 scans
    # (15, 17, 19); 21 has no odometry; 0.6 m from 19's position at 25 and 29
    assert kept == [0, 4, 8, 13, 15, 17, 19, 25, 29]


def test_relation_ends_are_kept_and_restart_the_count(bench) -> None:
    ends = np.array([STAMPS[6], STAMPS[21], STAMPS[2] + 1e-3])  # the last matches nothing
    kept = bench.thin_indices(STAMPS, path_odometry(), ends, 0.5, 10.0)
    # 6 restarts the count: 10 (0.5 m on); 21 is kept without odometry: 25 still counts
    # from 19
    assert kept == [0, 4, 6, 10, 13, 15, 17, 19, 21, 25, 29]


def test_the_coarser_rule_keeps_fewer(bench) -> None:
    kept = bench.thin_indices(STAMPS, path_odometry(), np.array([]), 1.0, 20.0)
    # 1 m = 8 steps; turning, 24° at 15 and 19; 1.05 m from 19's position at 28
    assert kept == [0, 8, 15, 19, 28]


# -- the written logs -----------------------------------------------------------------------
def flaser_scan(k: int, stamp: float, range_max: float) -> LaserScan:
    ranges = 2.0 + 0.01 * k + 0.5 * np.sin(np.arange(180) / 7.0)
    ranges[5] = range_max  # "no return": invalid
    ranges[6] = np.nan
    return LaserScan(
        ranges, -math.pi / 2, math.pi / 180, range_max=range_max, stamp=stamp
    )  # 180 beams from −90°, 1° apart: FLASER's "resolution" convention


def write_log(path: Path, range_maxes: list[float]) -> list[LogRecord]:
    odo = path_odometry()
    records = [
        LogRecord(flaser_scan(k, t, range_maxes[k]), Pose2D(*(o or (0.0, 0.0, 0.0))))
        for k, (t, o) in enumerate(zip(STAMPS, odo))
    ]
    write_carmen(path, records)
    return records


def test_a_thinned_log_holds_exactly_the_scans_kept(bench, tmp_path) -> None:
    log = tmp_path / "syn.clf"
    write_log(log, [30.0] * len(STAMPS))
    rel = tmp_path / "syn.relations"
    rel.write_text(f"{STAMPS[6]!r} {STAMPS[9]!r} 0.375 0 0 0 0 0\n")
    out = tmp_path / "thin.clf"
    info = bench.thin_log(log, rel, out, 0.5, 10.0)
    back = list(open_log(out).records())
    # the relation's ends 6 and 9 restart the count: 13 (12°) …; 21's odometry is
    # (0, 0, 0) in this log, 1.375 m from 19's: kept, and 22 is 1.46 m from it; then 26
    expected = [0, 4, 6, 9, 13, 15, 17, 19, 21, 22, 26]
    assert [r.scan.stamp for r in back] == [STAMPS[k] for k in expected]
    assert info == {
        "scans_full": 30,
        "scans_kept": 11,
        "relation_end_scans": 2,
        "lines": "FLASER",
    }
    assert out.read_text().count("\nFLASER ") == 11


def test_each_scan_keeps_its_own_valid_readings_whatever_its_range_max(bench, tmp_path) -> None:
    """A FLASER log has one maximum range: scans of different ``range_max`` still read back
    with their own valid readings (one_range_max), and the check notices a difference."""
    log = tmp_path / "mixed.clf"
    records = write_log(log, [30.0] * len(STAMPS))
    mixed = [
        LogRecord(flaser_scan(k, r.scan.stamp, 2.2 if k % 2 else math.inf), r.odometry)
        for k, r in enumerate(records)
    ]
    assert any(not s.scan.valid.all() for s in mixed)
    out = tmp_path / "thin.clf"
    assert bench.write_thinned(out, mixed, "mixed") == "FLASER"
    bench.check_read_back(out, mixed)
    back = list(open_log(out).records())
    for a, b in zip(mixed, back):
        np.testing.assert_array_equal(a.scan.valid, b.scan.valid)
    shifted = [mixed[0], LogRecord(flaser_scan(1, mixed[1].scan.stamp, 2.3), mixed[1].odometry)]
    with pytest.raises(ValueError, match=r"scan 1 reads back with another .*validity"):
        bench.check_read_back(out, shifted + mixed[2:])


def test_scans_flaser_cannot_describe_are_written_as_robotlaser1(bench, tmp_path) -> None:
    """fr-clinic's kind: 180 and 181 beams with interlaced start angles, the laser ahead."""
    records = []
    for k in range(6):
        n = 181 if k % 2 == 0 else 180
        a0 = -1.570796 if n == 181 else -1.566433  # fr-clinic's, to 6 decimals
        ranges = 3.0 + 0.1 * np.cos(np.arange(n) / 5.0 + k)
        ranges[3] = 81.9
        scan = LaserScan(
            ranges, a0, 0.017453, range_max=81.9, stamp=100.0 + k,
            sensor_pose=Pose2D(0.22, 0.0, 0.0),
        )  # fmt: skip
        records.append(LogRecord(scan, Pose2D(0.3 * k, 0.01 * k, 0.05 * k)))
    out = tmp_path / "clinic.clf"
    assert bench.write_thinned(out, records, "clinic") == "ROBOTLASER1"
    bench.check_read_back(out, records)
    text = out.read_text()
    assert text.count("\nROBOTLASER1 ") == 6 and "\nFLASER " not in text
    moved = [records[0], LogRecord(records[1].scan, Pose2D(9.0, 0.0, 0.0)), *records[2:]]
    with pytest.raises(ValueError, match="scan 1 reads back with another odometry"):
        bench.check_read_back(out, moved)


def test_the_peers_thinned_choices(bench, tmp_path) -> None:
    assert "intel-thin-0.5" in bench.thinned_names() and "fr-clinic-thin-1" in bench.thinned_names()
    with pytest.raises(KeyError):
        bench.thinned_log(tmp_path, tmp_path, "intel-thin-2")


def test_bench_peers_offers_the_thinned_logs(monkeypatch, capsys) -> None:
    peers = load_benchmark("bench_peers")
    assert "aces-thin-1" in peers.thinned_names()
    monkeypatch.setattr("sys.argv", ["bench_peers.py", "--logs", "aces-thin-3"])
    with pytest.raises(SystemExit, match=r"unknown log\(s\) aces-thin-3 .*aces-thin-0\.5"):
        peers.main()
