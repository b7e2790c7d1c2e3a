"""Issue 35: inputs that were read wrongly or refused badly. Each test fails without its fix;
bad input is one line ``fuzzypos: error: …`` and exit 2, never a traceback."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.config import Config
from fuzzypos.io import CarmenReader, open_log
from helpers import invoke, make_bag, one_line_error, write_sim_log

runner = CliRunner()


def flaser(ranges, odom, t: float) -> str:
    r = " ".join(str(v) for v in ranges)
    ox, oy, ot = odom
    return f"FLASER {len(ranges)} {r} {ox} {oy} {ot} {ox} {oy} {ot} {t!r} host {t!r}\n"


def small_log(path, n: int = 5, *, stamps=None) -> str:
    """``n`` 3-beam scans, the odometry moving 0.1 m a scan, 0.1 s apart."""
    stamps = [0.1 * k for k in range(n)] if stamps is None else stamps
    text = "".join(flaser([1.0, 2.0, 3.0], (0.1 * k, 0, 0), t) for k, t in enumerate(stamps))
    path.write_text(text)
    return text


# -- 1. a byte order mark ---------------------------------------------------------------------
def test_a_byte_order_mark_keeps_the_first_scan(tmp_path):
    path = tmp_path / "bom.clf"
    text = small_log(path, 4)
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    reader = CarmenReader(path)
    stamps = [rec.scan.stamp for rec in reader.records()]
    assert stamps == [0.0, 0.1, 0.2, 0.30000000000000004] and reader.bad_lines == 0
    assert len(reader.scan_stamps()) == 4


# -- 5. a symlink loop, a device that never ends ----------------------------------------------
def test_a_symlink_loop_is_named_as_one(tmp_path):
    a, b = tmp_path / "a.clf", tmp_path / "b.clf"
    a.symlink_to(b)
    b.symlink_to(a)
    for cmd in ("info", "run"):
        line = one_line_error([cmd, str(a)], f"{a}: symlink loop")
        assert "No such file" not in line


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_a_device_of_zeros_is_refused_at_once():
    # in a process of its own: without the fix it reads /dev/zero until the timeout
    code = "import sys; from fuzzypos.cli import main; sys.argv[0] = 'fuzzypos'; main()"
    for cmd in ("info", "run"):
        res = subprocess.run(
            [sys.executable, "-c", code, cmd, "/dev/zero"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert res.returncode == 2, res.stderr
        lines = res.stderr.splitlines()
        assert len(lines) == 1 and "/dev/zero: not a log: binary content" in lines[0], lines


# -- 4. a stretch beyond the log's end --------------------------------------------------------
def test_a_start_beyond_the_end_says_the_stretch_is_empty(tmp_path):
    path = tmp_path / "short.clf"
    small_log(path, 5, stamps=[100.0 + 0.5 * k for k in range(5)])
    line = one_line_error(
        ["run", str(path), "--start", "50", "--results", str(tmp_path / "r")],
        f"{path}: the stretch (--start 50 s",
        "holds no scans",
        "from stamp 100.0 to 102.0 (2.000 s",
    )
    assert "FLASER" not in line


# -- 8. --scan-rate -----------------------------------------------------------------------------
def test_corrupt_stamps_are_refused_naming_scan_rate(tmp_path):
    path = tmp_path / "equal.clf"
    small_log(path, 12, stamps=[5.0] * 12)
    one_line_error(
        ["run", str(path), "--results", str(tmp_path / "r")],
        f"{path}: the scans' stamps are corrupt",
        "pass --scan-rate HZ",
    )


def test_scan_rate_stamps_the_scans_evenly(tmp_path):
    path = tmp_path / "equal.clf"
    small_log(path, 12, stamps=[5.0] * 12)
    out = tmp_path / "r"
    lines = invoke(["run", str(path), "--scan-rate", "10", "--results", str(out)], 0)
    assert not any("warning" in ln for ln in lines), lines
    rows = [ln.split() for ln in (out / "trajectory.tum").read_text().splitlines()]
    stamps = [float(r[0]) for r in rows if not r[0].startswith("#")]
    assert stamps == [k / 10 for k in range(12)]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scan_rate_hz"] == 10.0 and summary["scans"] == 12
    assert any("evenly spaced 0.1 s apart" in n for n in summary["notes"])
    info = invoke(["info", str(path), "--scan-rate", "10", "--json"], 0)
    assert json.loads("\n".join(info))["duration_s"] == pytest.approx(1.1)
    one_line_error(["run", str(path), "--scan-rate", "0"], "--scan-rate must be a finite rate > 0")


# -- 3. absurd ranges ---------------------------------------------------------------------------
def test_absurd_ranges_are_invalid_and_written_as_read(tmp_path):
    path = tmp_path / "absurd.clf"
    lines = []
    for k in range(8):
        ranges = [2.0 + 0.01 * j for j in range(20)]
        if k % 2:
            ranges[3:6] = ["1e308", "1e308", "1e309"]
        lines.append(flaser(ranges, (0.05 * k, 0, 0), 0.1 * k))
    path.write_text("".join(lines))
    records = list(CarmenReader(path).records())
    scan = records[1].scan
    assert not scan.valid[3:6].any() and scan.valid[6:].all()
    assert math.isinf(scan.range_max)  # 1e308 twice is no scanner's "no return" value
    out = tmp_path / "r"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warning
        res = invoke(["run", str(path), "--results", str(out), "--max-scans", "4"], 0)
    assert not any("overflow" in ln or "warning" in ln for ln in res), res
    text = (out / "trajectory.clf").read_text().splitlines()
    written = [ln for ln in text if ln.startswith("FLASER")]
    second = written[1].split()
    assert second[5:8] == ["1e+308", "1e+308", "inf"], second[:10]
    assert max(len(t) for ln in written for t in ln.split()) < 30  # no 309-digit numbers
    again = list(CarmenReader(out / "trajectory.clf").records())
    assert not again[1].scan.valid[3:6].any() and again[1].scan.valid[6:].all()


# -- 2 and 7: odometry that does not cover the scans --------------------------------------------
@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """A simulated log of 32 scans (about 0.9 m along a circle) and its run."""
    path = tmp_path_factory.mktemp("sim") / "sim.clf"
    return path, write_sim_log(path)


def _with_odometry(src, dst, change) -> None:
    """``src`` with each FLASER line's six pose fields replaced by ``change(k, fields)``."""
    out, k = [], 0
    for line in src.read_text().splitlines(True):
        if line.startswith("FLASER "):
            t = line.split(" ")
            p = 2 + int(t[1])
            t[p : p + 6] = change(k, t[p : p + 6])
            k += 1
            line = " ".join(t)
        out.append(line)
    dst.write_text("".join(out))


def _summary(out):
    return json.loads((out / "summary.json").read_text())


def _travelled(out) -> float:
    rows = [ln.split() for ln in (out / "trajectory.tum").read_text().splitlines()]
    xy = np.array([[float(r[1]), float(r[2])] for r in rows if not r[0].startswith("#")])
    return float(np.linalg.norm(xy[-1] - xy[0]))


@pytest.mark.parametrize("skip", [False, True])
def test_a_nan_odometry_field_loses_only_that_scans_odometry(sim, tmp_path, skip):
    path = tmp_path / "nan.clf"
    _with_odometry(sim[0], path, lambda k, f: [*f[:3], "nan", *f[4:]] if k == 10 else f)
    out = tmp_path / "r"
    args = ["run", str(path), "--results", str(out), *(["--skip-bad-lines"] if skip else [])]
    lines = invoke(args, 0)
    s = _summary(out)
    assert s["scans"] == 32 and s["bad_lines_skipped"] == 0 and not s["partial"]
    assert s["odometry_coverage"]["scans_without_odometry"] == 1
    assert s["odometry_coverage"]["without_odometry_first"] == [10]
    assert any("1 FLASER lines have odometry fields that are not finite" in n for n in s["notes"])
    assert any(ln.startswith("note: odometry coverage: 1 of 32 scans") for ln in lines), lines
    res = runner.invoke(app, [*args[:3], str(tmp_path / "r2"), *args[4:]])
    assert "note: odometry coverage" in res.stderr and "note:" not in res.stdout
    assert s["truth_errors"]["estimate"]["mean_position_error_m"] < 0.05
    info = invoke(["info", str(path)], 0)
    assert any("odometry" in ln and "31 scans" in ln and "1 scans not covered" in ln for ln in info)


def test_odometry_all_zero_while_the_scans_move_is_detected(sim, tmp_path):
    path = tmp_path / "zero.clf"
    _with_odometry(sim[0], path, lambda k, f: ["0"] * 6)
    out = tmp_path / "r"
    lines = invoke(["run", str(path), "--results", str(out)], 0)
    s = _summary(out)
    cov = s["odometry_coverage"]
    assert cov["scans_with_stuck_odometry"] == 32 and cov["stuck_stretches"] == [[0, 31]]
    assert any("odometry stands exactly still while the scans show" in ln for ln in lines)
    truth = sim[1]
    moved = math.dist(truth.true_pose(0).as_array()[:2], truth.true_pose(31).as_array()[:2])
    assert _travelled(out) == pytest.approx(moved, abs=0.15)  # not frozen at the start
    info = invoke(["info", str(path)], 0)
    assert any("none that covers the scans (32 scans not covered" in ln for ln in info), info


def test_odometry_standing_still_with_still_scans_is_not_flagged(sim, tmp_path):
    path = tmp_path / "still.clf"
    _with_odometry(sim[0], path, lambda k, f: ["0"] * 6)
    first = next(ln for ln in path.read_text().splitlines(True) if ln.startswith("FLASER "))
    still = "".join(first.replace(" 0.0 host", f" {0.1 * k!r} host", 1) for k in range(20))
    path.write_text(still)
    from fuzzypos.io.logs import survey_log

    _, coverage = survey_log(open_log(path), Config().scanner)
    assert coverage.scans == 20 and coverage.uncovered == 0 and coverage.note() is None


def _bag_of(tmp_path, run, *, odom_shift=0.0, odom_from=0, bad_angle_max=()):
    stamps = [float(s.stamp) for s in run.scans]

    def build(b):
        msgs = []
        for k, scan in enumerate(run.scans):
            a_max = scan.angle_min + (scan.n_beams - 1) * scan.angle_increment
            extra = {"angle_max": a_max + (0.2 if k in bad_angle_max else 0.0)}
            msg = b.scan(
                stamps[k],
                scan.ranges,
                angle_min=scan.angle_min,
                angle_increment=scan.angle_increment,
                range_max=30.0,
                **extra,
            )
            msgs.append(("/scan", stamps[k] + 0.001, msg))
        for k in range(odom_from, len(stamps)):
            o = run.odometry_pose(k)
            t = stamps[k] + odom_shift
            msgs.append(("/odom", t + 0.001, b.odom(t, (o.x, o.y, o.theta))))
        msgs.sort(key=lambda m: m[1])
        return msgs

    return make_bag(tmp_path, "ros2", build)


def test_a_bag_whose_odometry_clock_is_off_is_detected(sim, tmp_path):
    bag = _bag_of(tmp_path, sim[1], odom_shift=1000.0)
    out = tmp_path / "r"
    lines = invoke(["run", str(bag), "--results", str(out)], 0)
    s = _summary(out)
    assert s["odometry_coverage"]["scans_without_odometry"] == 32
    assert any("32 of 32 scans lie outside the odometry's time span" in n for n in s["notes"])
    assert any("note: odometry coverage: 32 of 32 scans" in ln for ln in lines)
    truth = sim[1]
    moved = math.dist(truth.true_pose(0).as_array()[:2], truth.true_pose(31).as_array()[:2])
    assert _travelled(out) == pytest.approx(moved, abs=0.15)
    info = invoke(["info", str(bag)], 0)
    assert any("none that covers the scans" in ln for ln in info), info


def test_a_bag_odometry_starting_late_and_angle_max_mismatches_are_reported(sim, tmp_path):
    bag = _bag_of(tmp_path, sim[1], odom_from=12, bad_angle_max=(3, 4))
    out = tmp_path / "r"
    lines = invoke(["run", str(bag), "--results", str(out)], 0)
    s = _summary(out)
    assert s["odometry_coverage"]["scans_without_odometry"] == 12 - 2  # two periods' reach
    for text in ("10 of 32 scans lie outside the odometry's time span", "2 of 32 scan messages"):
        assert any(text in n for n in s["notes"]), (text, s["notes"])
        assert any(text in ln for ln in lines), (text, lines)
    info = invoke(["info", str(bag)], 0)
    assert any("2 of 32 scan messages have an angle_max" in ln for ln in info), info
    assert any("22 scans); 10 scans not covered" in ln for ln in info), info
