"""``fuzzypos info BAG`` (issue 35): every topic with its type and count, the scan and
odometry topics' frames, rates and stamps, the transforms on /tf and /tf_static, and the
topics and frames fuzzypos uses by default (:func:`fuzzypos.io.bag_info.describe_bag`)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.io.bag_info import BagFrameError, TfPair, _header, describe_bag, output_frames
from helpers import DATA, ODOM_T, SCAN_T, BagBuilder, make_bag, odd_frames, scan_ranges

runner = CliRunner()
KINDS = ["ros1", "ros2-sqlite3", "ros2-mcap"]


@pytest.mark.parametrize("kind", KINDS)
def test_describe_bag_topics_frames_rates_and_tf(tmp_path, kind):
    bag = make_bag(tmp_path, kind, odd_frames)
    info = describe_bag(bag)
    assert info.ros_version == (1 if kind == "ros1" else 2)
    topics = {t.topic: (t.msgtype, t.messages) for t in info.topics}
    assert topics == {
        "/scan": ("sensor_msgs/msg/LaserScan", len(SCAN_T)),
        "/wheel_odom": ("nav_msgs/msg/Odometry", len(ODOM_T)),
        "/tf": ("tf2_msgs/msg/TFMessage", len(ODOM_T) // 4),
        "/tf_static": ("tf2_msgs/msg/TFMessage", 1),
    }
    streams = {s.topic: s for s in info.streams}
    scan, odom = streams["/scan"], streams["/wheel_odom"]
    assert scan.frame_ids == {"laser": len(SCAN_T)} and scan.child_frame_ids is None
    assert odom.frame_ids == {"wheels": len(ODOM_T)}
    assert odom.child_frame_ids == {"chassis": 72, "chassis_old": 8}
    assert scan.first_stamp == pytest.approx(SCAN_T[0]) and scan.last_stamp == pytest.approx(
        SCAN_T[-1]
    )
    assert scan.span_s == pytest.approx(SCAN_T[-1] - SCAN_T[0])
    assert scan.rate_hz == pytest.approx(1 / 0.37) and scan.median_rate_hz == pytest.approx(
        1 / 0.37
    )
    assert odom.rate_hz == pytest.approx(10.0) and odom.span_s == pytest.approx(7.9)
    pairs = [(p.topic, p.parent, p.child, p.count) for p in info.tf]
    assert pairs == [
        ("/tf", "world", "wheels", len(ODOM_T) // 4),  # the leading / dropped
        ("/tf_static", "chassis", "laser_mount", 1),
        ("/tf_static", "laser_mount", "laser", 1),
    ]
    assert (info.scan_topic, info.odom_topic) == ("/scan", "/wheel_odom")
    f = info.frames
    assert (f.base, f.odom, f.map) == ("chassis", "wheels", "world")
    assert "child_frame_id" in f.sources["base"] and "header.frame_id" in f.sources["odom"]
    assert f.sources["map"] == "/tf: the parent of wheels"


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite3"])
def test_header_read_without_decoding_matches_the_decoded_message(kind):
    b = BagBuilder(1 if kind == "ros1" else 2)
    for frame, child in (("", "a"), ("odom", ""), ("odo", "base_footprint"), ("abcd", "xyz")):
        msg = b.odom(12.25, (1.0, 2.0, 0.3), child=child, frame=frame)
        t, got_frame, got_child = _header(b.serialize(msg), kind != "ros1", True)
        assert (t, got_frame, got_child) == (12.25, frame, child)
        scan = b.scan(3.5, scan_ranges(0), frame=frame)
        assert _header(b.serialize(scan), kind != "ros1", False) == (3.5, frame, None)


def test_two_scan_topics_pick_none_and_list_them(tmp_path):
    def build(b):
        return [(topic, 1.0, b.scan(1.0, scan_ranges(0))) for topic in ("/b", "/a")]

    bag = make_bag(tmp_path, "ros1", build)
    info = describe_bag(bag)
    assert info.scan_topic is None and info.scan_candidates == ["/a", "/b"]
    assert info.odom_topic is None and info.odom_candidates == []
    assert describe_bag(bag, scan_topic="/b").scan_topic == "/b"
    f = info.frames  # no odometry, no /tf: REP-105's names
    assert (f.base, f.odom, f.map) == ("base_link", "odom", "map")
    assert set(f.sources.values()) == {"REP-105's default"}


def test_output_frames_given_and_checked():
    tf = [TfPair("/tf", "odom", "base_link", 3), TfPair("/tf", "earth", "odom", 3)]
    f = output_frames({"base": "/robot", "odom": None}, odom_frame=None, tf=tf)
    assert (f.base, f.odom, f.map) == ("robot", "odom", "earth")
    assert f.sources == {"base": "given", "odom": "REP-105's default",
                         "map": "/tf: the parent of odom"}  # fmt: skip
    f = output_frames({}, tf=tf)
    assert (f.base, f.odom, f.map) == ("base_link", "odom", "earth")
    with pytest.raises(BagFrameError, match="must differ"):
        output_frames({"map": "odom"})
    for bad in ("", "two words", "/"):
        with pytest.raises(BagFrameError, match="without spaces"):
            output_frames({"base": bad})


def test_cli_info_on_a_bag_lists_topics_frames_and_tf(tmp_path):
    bag = make_bag(tmp_path, "ros2-sqlite3", odd_frames)
    r = runner.invoke(app, ["info", str(bag)], terminal_width=250)
    assert r.exit_code == 0, r.output
    out = r.output
    for text in ("/wheel_odom", "nav_msgs/msg/Odometry", "sensor_msgs/msg/LaserScan",
                 "chassis (72), chassis_old (8)", "wheels", "10.00 Hz", "2.70 Hz",
                 "world → wheels", "chassis → laser_mount", "laser_mount → laser",
                 "scan topic", "odometry topic", "--map-frame"):  # fmt: skip
        assert text in out, (text, out)
    data = json.loads(runner.invoke(app, ["info", str(bag), "--json"]).stdout)
    assert data["scans"] == len(SCAN_T)
    assert data["bag"]["frames"]["map"] == "world"
    assert {t["topic"] for t in data["bag"]["topics"]} == {"/scan", "/wheel_odom", "/tf",
                                                          "/tf_static"}  # fmt: skip


def test_cli_info_on_a_carmen_log_has_no_bag_part(tmp_path):
    from helpers import write_sim_log

    log = tmp_path / "sim.clf"
    write_sim_log(log, laps=0.02)
    data = json.loads(runner.invoke(app, ["info", str(log), "--json"]).stdout)
    assert "bag" not in data and data["scans"] > 0


def test_info_on_the_fr079_bag():
    bag = DATA / "fr079" / "fr079.bag"
    if not bag.is_file():
        pytest.skip(f"no {bag}")
    info = describe_bag(bag)
    streams = {s.topic: s for s in info.streams}
    assert streams["/scan"].messages == 4934 and streams["/scan"].frame_ids == {"laser": 4934}
    assert streams["/odom"].child_frame_ids == {"base_link": 8951}
    assert 4.0 < streams["/scan"].rate_hz < 5.0
    assert ("/tf_static", "base_link", "laser") in {(p.topic, p.parent, p.child) for p in info.tf}


@pytest.mark.parametrize("scan_topics", [(), ("/a", "/b")], ids=["no scans", "two scan topics"])
def test_cli_info_on_a_bag_without_one_scan_topic_shows_the_bag(tmp_path, scan_topics):
    """A bag ``run --bag-out`` wrote (no LaserScan) or one with two scan topics is still
    described (exit 0): its topics and defaults, and a note of what ``run`` needs."""
    from helpers import standard

    bag = make_bag(tmp_path, "ros1", lambda b: standard(b, scan_topics=scan_topics))
    r = runner.invoke(app, ["info", str(bag)], terminal_width=250)
    assert r.exit_code == 0, r.output
    assert "nav_msgs/msg/Odometry" in r.stdout and "Traceback" not in r.output
    for t in scan_topics:
        assert t in r.stdout
    note = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(note) == 1 and note[0].startswith("note: ")
    assert ("pass --scan-topic" in note[0]) == bool(scan_topics)
    data = json.loads(runner.invoke(app, ["info", str(bag), "--json"]).stdout)
    assert data["bag"]["scan_candidates"] == sorted(scan_topics)
    assert "scans" not in data  # no scans read
    # naming a topic that is not there is the user's error: one line, exit 2
    r = runner.invoke(app, ["info", str(bag), "--scan-topic", "/nope"])
    assert r.exit_code == 2 and "/nope" in r.stderr
