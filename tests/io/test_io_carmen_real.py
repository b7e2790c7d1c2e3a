"""fuzzypos.io.carmen on the shared real logs (intel, aces): whole-file checks.

The logs live in ../shared/data (read-only, never copied here); every test skips, with
the reason, where they are absent. Each reads a whole log (intel: 16 MB of text, ~2-3 s).
"""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from fuzzypos.io import CarmenReader
from helpers import DATA

INTEL = DATA / "intel" / "intel.clf.gz"
ACES = DATA / "aces" / "aces.clf.gz"
DEG = math.pi / 180.0


def _need(path: Path) -> None:
    if not path.exists():
        pytest.skip(f"shared data {path} is absent")


def _odom_stream(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The ODOM lines' stamps and poses, read independently of the reader."""
    t, p = [], []
    with gzip.open(path, "rt") as fh:
        for line in fh:
            if line.startswith("ODOM "):
                tok = line.split()
                p.append((float(tok[1]), float(tok[2]), float(tok[3])))
                t.append(float(tok[7]))
    return np.array(t), np.array(p)


# log, scans, ODOM lines, "no return" value, its readings, scan stamps going backwards
LOGS = [
    pytest.param(INTEL, 13_631, 26_915, 81.83, 68_313, 631, id="intel"),
    pytest.param(ACES, 7_374, 7_375, 50.0, 11_139, 0, id="aces"),
]


@pytest.mark.parametrize("path, scans, odoms, no_return, n_no_return, backwards", LOGS)
def test_whole_log(path, scans, odoms, no_return, n_no_return, backwards):
    _need(path)
    rd = CarmenReader(path)
    n = invalid = wrong_invalid = 0
    stamps = []
    for rec in rd:
        scan = rec.scan
        assert scan.n_beams == 180
        assert scan.angle_min == -90 * DEG and scan.angle_increment == pytest.approx(DEG)
        bad = ~scan.valid
        invalid += int(bad.sum())
        # invalid readings are exactly the "no return" ones, nothing else
        wrong_invalid += int(np.count_nonzero(bad != (scan.ranges == no_return)))
        stamps.append(scan.stamp)
        n += 1
    assert n == scans and rd.odom_messages == odoms
    assert invalid == n_no_return and wrong_invalid == 0
    assert rd.no_return_value == no_return
    assert int(np.count_nonzero(np.diff(stamps) < 0)) == backwards  # file order kept
    assert rd.bad_lines == 0 and not rd.truncated and rd.params == {}


def test_aces_interpolated_odometry_matches_an_independent_interpolation():
    """aces: both streams' stamps increase, so odometry="interpolated" is plain interpolation
    in time over the whole ODOM stream (lines interleave out of time order 161 times)."""
    _need(ACES)
    ot, op = _odom_stream(ACES)
    assert np.all(np.diff(ot) >= 0)
    recs = list(CarmenReader(ACES, odometry="interpolated"))
    t = np.array([r.scan.stamp for r in recs])
    got = np.array([tuple(r.odometry) for r in recs])
    i = np.searchsorted(ot, t, side="right") - 1  # the latest ODOM at or before
    j = np.searchsorted(ot, t, side="left")  # the earliest at or after
    assert np.all(i >= 0) and np.all(j < ot.size)  # aces: every scan inside the stream
    span = ot[j] - ot[i]
    s = np.divide(t - ot[i], span, out=np.zeros_like(t), where=span > 0)
    d = op[j] - op[i]
    d[:, 2] = np.angle(np.exp(1j * d[:, 2]))
    want = op[i] + s[:, None] * d
    np.testing.assert_allclose(got[:, :2], want[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got[:, 2] - want[:, 2]))), 0.0, atol=1e-9)
    # and it stays close to the scans' own odometry fields (a different source)
    own = np.array([tuple(r.odometry) for r in CarmenReader(ACES)])
    dxy = np.hypot(*(got[:, :2] - own[:, :2]).T)
    assert np.median(dxy) < 0.05 and np.percentile(dxy, 99) < 0.3


def test_intel_interpolated_streams_in_file_order_with_bounded_memory():
    """intel: stamps go backwards in both streams; the records still come in file order, the
    ODOM window stays bounded, and the interpolated poses are at times far (tens of cm, tens
    of degrees) from the scans' own fields, as the README of the data warns."""
    _need(INTEL)
    own = [(r.scan.stamp, tuple(r.odometry)) for r in CarmenReader(INTEL)]
    rd = CarmenReader(INTEL, odometry="interpolated")
    got, window = [], 0
    for rec in rd:
        got.append((rec.scan.stamp, tuple(rec.odometry)))
        window = max(window, len(rd._odoms))
    assert [s for s, _ in got] == [s for s, _ in own]
    assert window <= 16 + 100
    a = np.array([p for _, p in own])
    b = np.array([p for _, p in got])
    dxy = np.hypot(*(a[:, :2] - b[:, :2]).T)
    dth = np.abs(np.angle(np.exp(1j * (a[:, 2] - b[:, 2]))))
    assert np.median(dxy) < 0.01 and np.median(dth) < 0.5 * DEG  # mostly the same ...
    assert dxy.max() > 0.2 and dth.max() > 20 * DEG  # ... but not where scans come in bursts
