"""fuzzypos.io.logs: telling a log's kind by content, choosing a stretch, describing a log."""

from __future__ import annotations

import gc
import gzip
import math
import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzypos.geometry import Pose2D
from fuzzypos.io import (
    BagReader,
    CarmenReader,
    LogFormatError,
    LogRecord,
    UnknownLogError,
    describe_log,
    log_kind,
    open_log,
)
from fuzzypos.io.logs import (
    SelectionError,
    StampCheck,
    StampError,
    parse_laser_offset,
    select_records,
    select_stamps,
)
from fuzzypos.scan import LaserScan
from helpers import SCAN_T, fifo_with, make_bag, pipe_with, scan_ranges, standard, write_sim_log


# -- helpers ----------------------------------------------------------------------------
def fake_records(stamps: list[float]) -> list[LogRecord]:
    """Records of 3-beam scans at the given stamps (odometry = (k, 0, 0))."""
    return [
        LogRecord(LaserScan(np.ones(3), -0.1, 0.1, stamp=t), Pose2D(float(k), 0.0, 0.0))
        for k, t in enumerate(stamps)
    ]


CARMEN_TEXT = "# a CARMEN log\nFLASER 3 1.0 2.0 3.0 0 0 0 0 0 0 5.0 host 5.0\n"


# -- telling the kind by content -------------------------------------------------------------
def test_a_carmen_log_named_bag_is_carmen(tmp_path):
    plain = tmp_path / "run.bag"
    plain.write_text(CARMEN_TEXT)
    gz = tmp_path / "other.bag"
    gz.write_bytes(gzip.compress(CARMEN_TEXT.encode()))
    for p in (plain, gz):
        assert log_kind(p) == "carmen"
        log = open_log(p)
        assert log.kind == "carmen" and isinstance(log.reader, CarmenReader)
        recs = list(log.records())
        assert len(recs) == 1 and recs[0].scan.stamp == 5.0


def test_a_bag_named_clf_is_a_bag(tmp_path):
    bag = make_bag(tmp_path, "ros1", standard).rename(tmp_path / "looks_like.clf")
    assert log_kind(bag) == "ros1"
    log = open_log(bag)
    assert log.kind == "ros1" and isinstance(log.reader, BagReader)
    assert log.options["scan_topic"] == "/scan"
    assert len(list(log.records())) == len(SCAN_T)
    assert log.scan_count_hint() == len(SCAN_T)


def test_a_ros2_directory_is_ros2(tmp_path):
    bag = make_bag(tmp_path, "ros2-sqlite3", standard)
    assert log_kind(bag) == "ros2"
    log = open_log(bag)
    assert log.kind == "ros2" and len(list(log)) == len(SCAN_T)


def test_a_bag_without_odometry_says_so(tmp_path):
    bag = make_bag(tmp_path, "ros1", lambda b: standard(b, odometry=False))
    log = open_log(bag)
    assert any("without an odometry prior" in n for n in log.notes)
    assert all(r.odometry is None for r in log.records())


def test_options_for_the_other_kind_are_noted(tmp_path):
    bag = make_bag(tmp_path, "ros1", standard)
    log = open_log(bag, skip_bad_lines=True, field_of_view_deg=90, convention="span")
    assert sum("applies to CARMEN logs only" in n for n in log.notes) == 3
    text = tmp_path / "log.clf"
    text.write_text(CARMEN_TEXT)
    log = open_log(text, scan_topic="/scan")
    assert any("scan_topic applies to bags only" in n for n in log.notes)


@pytest.mark.parametrize(
    ("content", "expect"),
    [
        (b"\x00\x01\x02binary" * 50, "binary content"),
        (gzip.compress(b"\x00\xff" * 100), "gzip file whose content is binary"),
        (b"\x1f\x8bnot really gzip", "broken gzip"),
        (b"SQLite format 3\x00" + b"\x00" * 100, "storage file of a ROS2 bag"),
        (b"\x89MCAP0\r\n" + b"\x00" * 100, "storage file of a ROS2 bag"),
    ],
)
def test_anything_else_is_a_typed_error_naming_the_file(tmp_path, content, expect):
    p = tmp_path / "mystery.clf"
    p.write_bytes(content)
    with pytest.raises(UnknownLogError, match=expect) as info:
        open_log(p)
    assert isinstance(info.value, ValueError)
    assert str(info.value).startswith(str(p))


def test_a_directory_without_metadata_and_a_missing_path(tmp_path):
    with pytest.raises(UnknownLogError, match=r"without metadata\.yaml"):
        open_log(tmp_path)
    with pytest.raises(FileNotFoundError) as info:
        open_log(tmp_path / "nope.clf")
    assert info.value.filename == str(tmp_path / "nope.clf")


def test_utf8_cut_at_the_sniffed_block_is_still_text(tmp_path):
    p = tmp_path / "log.clf"
    body = ("#" + "é" * 5000 + "\n").encode()  # 2-byte characters straddle byte 8192
    p.write_bytes(body + CARMEN_TEXT.encode())
    assert log_kind(p) == "carmen"
    empty = tmp_path / "empty.clf"
    empty.write_bytes(b"")
    assert log_kind(empty) == "carmen"


def test_unknown_log_error_pickles():
    import pickle

    err = UnknownLogError("x.bin", "not a log: binary")
    back = pickle.loads(pickle.dumps(err))
    assert str(back) == str(err) and back.path == "x.bin"


def test_laser_offset_must_be_a_pose(tmp_path):
    p = tmp_path / "log.clf"
    p.write_text(CARMEN_TEXT)
    with pytest.raises(TypeError):
        open_log(p, laser_offset=(0.1, 0.0, 0.0))  # type: ignore[arg-type]
    log = open_log(p, laser_offset=Pose2D(0.1, 0.0, 0.0))
    assert next(iter(log)).scan.sensor_pose == Pose2D(0.1, 0.0, 0.0)


# -- select_records --------------------------------------------------------------------------
#            0     1     2     3     4     5     6     7
STAMPS = [100.0, 100.5, 101.0, 100.9, 102.0, 101.8, 103.0, 102.5]  # goes back twice


def _sel(**kw) -> list[int]:
    return [int(r.odometry.x) for r in select_records(fake_records(STAMPS), **kw)]


def test_select_everything_by_default():
    assert _sel() == list(range(8))


def test_select_start_is_the_first_scan_at_or_after_it_in_file_order():
    assert _sel(start=1.0) == [2, 3, 4, 5, 6, 7]  # 3 (rel 0.9) kept: after the beginning
    assert _sel(start=0.95) == [2, 3, 4, 5, 6, 7]
    assert _sel(start=2.0) == [4, 5, 6, 7]
    assert _sel(start=3.0) == [6, 7]
    assert _sel(start=3.5) == []


def test_select_end_stops_at_the_first_scan_beyond_it():
    assert _sel(end=1.0) == [0, 1, 2, 3]  # 4 (rel 2.0) stops it; 5 (rel 1.8) never comes
    assert _sel(end=1.9) == [0, 1, 2, 3]
    assert _sel(end=2.0) == [0, 1, 2, 3, 4, 5]
    assert _sel(start=0.5, end=0.5) == [1]
    assert _sel(end=0.0) == [0]


def test_select_max_scans_caps_the_count():
    assert _sel(max_scans=3) == [0, 1, 2]
    assert _sel(start=1.0, max_scans=2) == [2, 3]
    assert _sel(max_scans=100) == list(range(8))


def test_select_streams_and_reads_no_further_than_needed():
    consumed: list[int] = []

    def source():
        for k, rec in enumerate(fake_records(STAMPS)):
            consumed.append(k)
            yield rec

    out = list(select_records(source(), end=1.0))
    assert len(out) == 4 and consumed == [0, 1, 2, 3, 4]
    consumed.clear()
    assert len(list(select_records(source(), max_scans=2))) == 2 and consumed == [0, 1]


@pytest.mark.parametrize(
    "kw",
    [
        {"start": -1.0},
        {"end": math.nan},
        {"start": math.inf},
        {"start": "soon"},
        {"start": True},
        {"start": 2.0, "end": 1.0},
        {"max_scans": 0},
        {"max_scans": 2.5},
        {"max_scans": True},
    ],
)
def test_select_rejects_bad_arguments_at_once(kw):
    def never():
        raise AssertionError("must not be read")
        yield  # pragma: no cover

    with pytest.raises(SelectionError):
        select_records(never(), **kw)


# -- the laser offset ------------------------------------------------------------------------
def test_parse_laser_offset():
    p = parse_laser_offset("0.1, -0.02, 90")
    assert p.x == 0.1 and p.y == -0.02 and p.theta == pytest.approx(math.pi / 2)
    for bad in ("1,2", "1,2,3,4", "a,b,c", "1,nan,0", ""):
        with pytest.raises(SelectionError, match="laser-offset"):
            parse_laser_offset(bad)


# -- describe_log ------------------------------------------------------------------------------
def test_describe_a_simulated_log(tmp_path):
    p = tmp_path / "sim.clf"
    run = write_sim_log(p)
    info = describe_log(open_log(p))
    n = len(run)
    assert info.kind == "carmen" and info.scans == n
    assert info.beams == [run.scans[0].n_beams]
    assert info.first_stamp == run.stamps[0] and info.last_stamp == run.stamps[-1]
    assert info.duration_s == pytest.approx(run.stamps[-1] - run.stamps[0])
    assert info.has_odometry and info.has_truth and info.scans_with_truth == n
    assert info.stamps_backwards == 0 and info.bad_lines == 0
    assert info.angle_min_deg == pytest.approx(-90.0)
    d = info.as_dict()
    assert d["has_truth"] is True and d["scans"] == n


def test_describe_counts_backwards_stamps_and_skipped_lines(tmp_path):
    p = tmp_path / "odd.clf"
    p.write_text(
        "FLASER 3 1 1 1 0 0 0 0 0 0 10.0 h 10.0\n"
        "FLASER 3 1 1 1 0 0 0 0 0 0 9.5 h 9.5\n"
        "FLASER 3 1 1 0 0 0 0 0 9.7 h 9.7\n"  # one range short: malformed
        "FLASER 3 1 1 1 0 0 0 0 0 0 11.0 h 11.0\n"
    )
    info = describe_log(open_log(p, skip_bad_lines=True))
    assert info.scans == 3 and info.bad_lines == 1 and info.stamps_backwards == 1
    assert info.min_stamp == 9.5 and info.max_stamp == 11.0 and info.duration_s == 1.0
    assert not info.has_truth


# -- pipes -------------------------------------------------------------------------------------
def test_a_log_through_a_fifo_reads_whole(tmp_path):
    """``fuzzypos info <(zcat LOG.clf.gz)``: sniffing, counting and reading each see all of
    it (the issue: 1,979 of 1,988 scans and a wrong first stamp)."""
    p = tmp_path / "sim.clf"
    run = write_sim_log(p)
    with fifo_with(tmp_path, gzip.compress(p.read_bytes())) as fifo:
        log = open_log(fifo)
        assert log.kind == "carmen" and log.name == str(fifo) == str(log.path)
        assert log.scan_count_hint() == len(run)
        info = describe_log(log)
        assert len(list(log.records())) == len(run)  # again
    assert info.scans == len(run) and info.first_stamp == run.stamps[0]
    assert info.path == str(fifo)
    spool = os.fspath(log.path)
    assert spool != str(fifo) and os.path.isfile(spool)
    del log
    gc.collect()
    assert not os.path.exists(spool)  # the copy goes with the log


def test_a_bag_through_a_pipe_reads_whole(tmp_path):
    path = make_bag(tmp_path, "ros1", standard)
    with pipe_with(path.read_bytes()) as pipe:
        log = open_log(pipe)
    assert log.kind == "ros1" and log.name == str(pipe)
    assert describe_log(log).scans == len(SCAN_T)


# -- the stamps ------------------------------------------------------------------------------
def test_stamp_check_counts_and_judges():
    assert StampCheck.of([]).remark() is None and not StampCheck.of([5.0]).unusable
    ok = StampCheck.of([0.0, 0.1, 0.2, 0.15, 0.3, 0.4])  # backwards now and then: fine
    assert (ok.backwards, ok.repeated) == (1, 0) and not ok.corrupt and ok.remark() is None
    assert ok.largest_gap_s == pytest.approx(0.15) and ok.largest_gap_at == 4
    few = StampCheck.of([0.0, 0.1, 0.1, 0.2, 0.3, 0.4])
    assert few.repeated == 1 and not few.corrupt
    assert few.remark() == (
        "1 of 6 scans repeat the stamp of the scan before them: their odometry is judged over 0 s"
    )
    bad = StampCheck.of([7.0] * 1937 + [7.0 + 2.0**32, 7.0, 1.0, 2.0])
    assert bad.scans == 1941 and bad.repeated == 1936 and bad.backwards == 2
    assert bad.unusable and bad.corrupt
    assert "1,938 of 1,941 scans repeat or go back" in (bad.remark() or "")
    jump = StampCheck.of([0.0, 1.0, 2.0, 2.0 + 2.0**32, 3.0 + 2.0**32])
    assert jump.absurd_gap and jump.corrupt and not jump.unusable
    assert "jump forward by 4.29497e+09 s between scans 2 and 3" in (jump.remark() or "")


def _stamped_log(path, stamps):
    lines = [
        f"FLASER 3 1.0 2.0 3.0 0 0 0 {0.1 * k} 0 0 {t!r} host {t!r}" for k, t in enumerate(stamps)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_describe_reports_corrupt_stamps_instead_of_a_duration(tmp_path):
    path = _stamped_log(tmp_path / "corrupt.clf", [7.0] * 40 + [7.0 + 2.0**32, 9.0])
    with pytest.warns(RuntimeWarning, match=r"corrupt\.clf: the scans' stamps are corrupt: 40"):
        info = describe_log(open_log(path))
    assert info.duration_s is None and info.stamps_repeated == 39
    assert info.stamp_problem is not None and "40 of 42 scans" in info.stamp_problem
    assert info.as_dict()["stamp_problem"] == info.stamp_problem


def test_check_stamps_refuses_corrupt_stamps_and_warns_of_repeats(tmp_path):
    corrupt = open_log(_stamped_log(tmp_path / "corrupt.clf", [7.0] * 30 + [8.0]))
    with pytest.raises(StampError) as info:
        corrupt.check_stamps()
    err = info.value
    assert str(err).startswith(f"{corrupt.name}: the scans' stamps are corrupt: 29 of 31")
    assert isinstance(err, LogFormatError) and "\n" not in str(err)
    # a stretch of good stamps is not refused for what comes after it
    good_first = _stamped_log(tmp_path / "tail.clf", [float(k) for k in range(10)] + [20.0] * 30)
    assert open_log(good_first).check_stamps(max_scans=10).scans == 10
    with pytest.raises(StampError):
        open_log(good_first).check_stamps()
    few = open_log(_stamped_log(tmp_path / "few.clf", [0.0, 0.1, 0.1, 0.2, 0.3, 0.2, 0.4]))
    with pytest.warns(RuntimeWarning, match=r"few\.clf: 1 of 7 scans repeat the stamp"):
        check = few.check_stamps()
    assert check.repeated == 1 and check.backwards == 1


@given(
    st.lists(st.sampled_from([0.0, 0.5, 1.0, 1.5, 2.0, 3.0]), max_size=12),
    st.sampled_from([None, 0.0, 0.5, 1.0]),
    st.sampled_from([None, 0.5, 2.0]),
    st.sampled_from([None, 1, 3]),
)
def test_select_stamps_picks_what_select_records_picks(stamps, start, end, max_scans):
    if start is not None and end is not None and end < start:
        return
    kw = {"start": start, "end": end, "max_scans": max_scans}
    chosen = [r.scan.stamp for r in select_records(fake_records(stamps), **kw)]
    assert select_stamps(stamps, **kw).tolist() == chosen


def test_describe_a_bag_whose_scans_have_no_ranges(tmp_path):
    def build(b):
        empty = np.zeros(0, dtype=np.float32)
        return [("/scan", 1.0, b.scan(1.0, scan_ranges(0))), ("/scan", 2.0, b.scan(2.0, empty))]

    info = describe_log(open_log(make_bag(tmp_path, "ros1", build)))
    assert info.scans == 2 and info.scans_without_ranges == 1 and info.beams == [0, 9]
    assert info.angle_min_deg == pytest.approx(math.degrees(-1.2))
    assert any("1 scans have no ranges" in n for n in info.notes)
