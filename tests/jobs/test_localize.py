"""The localize job (``fuzzypos.jobs.localize``, issue 37) with a test double of the localizer
contract (``localizer_double``): a simulated log in the office world and the world drawn as a
map_server map. The poses written are the double's only where it is tracking, with its
covariances; the summary says when it localised, lost and found itself; a log that never
localises has no pose rows; bad input fails before anything is written; Ctrl-C and errors keep
the scans done; the bag has AMCL's pose and map → odom."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

import localizer_double as double
from fuzzypos import sim
from fuzzypos.errors import FuzzyposError
from fuzzypos.geometry import compose
from fuzzypos.io import open_log, read_tum
from fuzzypos.io.occupancy_map import MapError, MapFileError, read_map_yaml
from fuzzypos.jobs.folders import ResultsFolderError
from fuzzypos.jobs.localize import (
    AMCL_POSE_TOPIC,
    COVARIANCE_COLUMNS,
    InitialPoseOutsideMapError,
    LocalizeArgumentError,
    localize_log,
    localize_partial,
    parse_initial_pose,
    parse_initial_sigma,
)
from helpers import write_sim_log, write_world_map


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """A simulated log (half a lap of a 1 m circle in the office), the office as a map, and
    the truth of each scan's stamp as the log reads it (the double answers with it)."""
    folder = tmp_path_factory.mktemp("localize")
    log = folder / "sim.clf"
    write_sim_log(log, laps=0.5, seed=2)
    yaml_path, _, _ = write_world_map(folder / "map", sim.world_by_name("office"), 0.05)
    truth = {}
    for rec in open_log(log).records():
        truth[rec.scan.stamp] = (rec.truth.x, rec.truth.y, rec.truth.theta)
    return log, yaml_path, truth


@pytest.fixture(autouse=True)
def _truth(world, monkeypatch):
    monkeypatch.setattr(double, "TRUTH", world[2])


def covariance_rows(path: Path) -> tuple[list[str], np.ndarray, list[str]]:
    lines = path.read_text().splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    numbers = np.array([[float(v) for v in r[:-1]] for r in rows]).reshape(-1, 14)
    return lines[0].split(","), numbers, [r[-1] for r in rows]


def test_poses_are_written_only_where_tracking_with_their_covariance(world, tmp_path) -> None:
    log, yaml_path, truth = world
    make = double.factory(searching=6, lost=range(20, 25))
    out = tmp_path / "res"
    s = localize_log(log, yaml_path, results_dir=out, localizer=make)
    n = len(truth)
    tracked = [k for k in range(n) if k >= 6 and k not in range(20, 25)]
    assert s.scans == n and s.localised
    assert s.states == ["tracking" if k in tracked else "lost" if 20 <= k < 25 else "searching"
                        for k in range(n)]  # fmt: skip
    stamps = sorted(truth)  # the sim's stamps rise in file order
    t, poses = read_tum(out / "trajectory.tum")
    np.testing.assert_array_equal(t, [stamps[k] for k in tracked])
    want = np.array([truth[stamps[k]] for k in tracked])
    np.testing.assert_allclose(poses[:, :2], want[:, :2], atol=1e-12)
    np.testing.assert_allclose(np.cos(poses[:, 2] - want[:, 2]), 1.0, atol=1e-12)
    header, numbers, reasons = covariance_rows(out / "covariance.csv")
    assert tuple(header) == COVARIANCE_COLUMNS and reasons == ["matched"] * len(tracked)
    np.testing.assert_array_equal(numbers[:, 0], t)
    for row, k in zip(numbers, tracked):
        c, st = double.covariance_of(k), double.step_of(k)
        np.testing.assert_allclose(row[7:13], c[np.triu_indices(3)], rtol=1e-15)
        if k in (6, 25):  # the first scan tracked after searching or lost: no step
            assert np.all(np.isnan(row[1:7]))
        else:
            np.testing.assert_allclose(row[1:7], st[np.triu_indices(3)], rtol=1e-15)
    assert 0.5 <= row[13] <= 1.0
    # the double was made with the map and its config, and asked once per scan with odometry
    (loc,) = make.made
    assert loc.occupancy_map.source == yaml_path and loc.initial_pose is None
    assert len(loc.calls) == n and all(odom is not None for _, odom in loc.calls)


def test_the_summary_says_when_it_localised_lost_and_found_itself(world, tmp_path) -> None:
    log, yaml_path, truth = world
    stamps = sorted(truth)
    s = localize_log(log, yaml_path, results_dir=tmp_path / "r",
                     localizer=double.factory(searching=6, lost=range(20, 25)))  # fmt: skip
    data = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert data == json.loads(json.dumps(s.summary))
    assert data["localised"] is True and data["partial"] is False
    at = data["localised_at"]
    assert at["scan"] == 7 and at["stamp"] == stamps[6]
    assert at["seconds_since_first_scan"] == pytest.approx(stamps[6] - stamps[0])
    assert 0.0 <= at["wall_seconds"] <= data["seconds"]
    assert [(e["event"], e["scan"], e["stamp"]) for e in data["events"]] == [
        ("localised", 7, stamps[6]),
        ("lost", 21, stamps[20]),
        ("found", 26, stamps[25]),
    ]
    n = len(stamps)
    assert data["states"] == {"searching": 6, "tracking": n - 11, "lost": 5}
    assert data["reasons"] == {"matched": n - 11, "ambiguous": 6, "the map no longer fits": 5}
    assert data["scans"] == n and data["scans_with_pose"] == n - 11
    assert data["final_state"] == "tracking"
    conf = data["confidence"]
    assert sum(b["last_scan"] - b["first_scan"] + 1 for b in conf["blocks"]) == n
    first = conf["blocks"][0]
    assert first["min"] == pytest.approx(0.05) and first["tracking_share"] == pytest.approx(
        (min(n, conf["block_scans"]) - 11) / min(n, conf["block_scans"])
    )
    assert conf["quantiles_tracking"]["p5"] >= 0.5 > conf["quantiles"]["p5"]
    assert data["truth_errors"]["max_position_error_m"] < 1e-9  # the double answers the truth
    assert data["map"]["yaml"] == str(yaml_path) and data["map"]["resolution_m"] == 0.05
    assert data["map"]["cells"]["occupied"] > 0 and len(data["map"]["sha256"]) == 64
    assert data["input"]["kind"] == "carmen" and len(data["input"]["sha256"]) == 64
    assert "scanner" in data["config_values"] and data["fuzzypos_version"]
    assert sorted(data["files"]) == [
        "config.toml", "covariance.csv", "summary.json", "trajectory.tum"
    ]  # fmt: skip


def test_a_log_that_never_localises_has_no_pose_rows(world, tmp_path) -> None:
    log, yaml_path, truth = world
    s = localize_log(log, yaml_path, results_dir=tmp_path / "r",
                     localizer=double.factory(searching=None))  # fmt: skip
    assert not s.localised and s.poses.shape == (0, 3)
    t, _ = read_tum(tmp_path / "r" / "trajectory.tum")
    assert t.size == 0
    header, numbers, _ = covariance_rows(tmp_path / "r" / "covariance.csv")
    assert tuple(header) == COVARIANCE_COLUMNS and numbers.shape[0] == 0
    data = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert data["localised"] is False and data["localised_at"] is None and data["events"] == []
    assert data["states"] == {"searching": len(truth), "tracking": 0, "lost": 0}
    assert data["truth_errors"] is None and data["confidence"]["quantiles_tracking"] is None
    assert any("never localised" in note for note in data["notes"])


def test_the_initial_pose_reaches_the_localizer_and_one_off_the_map_is_refused(
    world, tmp_path
) -> None:
    log, yaml_path, _ = world
    make = double.factory()
    pose, sigma = parse_initial_pose("1,0,90"), parse_initial_sigma("0.5,10")
    localize_log(log, yaml_path, results_dir=tmp_path / "a", localizer=make,
                 initial_pose=pose, initial_sigma=sigma, max_scans=3)  # fmt: skip
    (loc,) = make.made
    assert loc.initial_pose == pytest.approx((1.0, 0.0, math.pi / 2))
    assert loc.initial_sigma == pytest.approx((0.5, math.radians(10.0)))
    data = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert data["initial_pose"] == pytest.approx({"x": 1.0, "y": 0.0, "theta_deg": 90.0})
    assert data["scans"] == 3
    out = tmp_path / "b"
    with pytest.raises(InitialPoseOutsideMapError) as info:
        localize_log(log, yaml_path, results_dir=out, localizer=make,
                     initial_pose=(40.0, 0.0, 0.0))  # fmt: skip
    message = str(info.value)
    assert (
        "(40 m, 0 m, 0°)" in message
        and str(yaml_path) in message
        and "x -10.50..10.50 m, y -5.50..5.50 m" in message
    )
    assert isinstance(info.value, ValueError) and isinstance(info.value, FuzzyposError)
    assert not out.exists() and len(make.made) == 1
    with pytest.raises(LocalizeArgumentError, match="initial_sigma needs initial_pose"):
        localize_log(log, yaml_path, results_dir=out, localizer=make, initial_sigma=sigma)


@pytest.mark.parametrize(
    ("text", "sigma"), [("1,2", False), ("a,b,c", False), ("1,2,nan", False), ("1", True),
                        ("0,5", True), ("0.3,-2", True)]
)  # fmt: skip
def test_bad_initial_pose_and_sigma_texts(text, sigma) -> None:
    with pytest.raises(LocalizeArgumentError, match=repr(text)):
        (parse_initial_sigma if sigma else parse_initial_pose)(text)


def test_parsed_pose_and_sigma() -> None:
    assert parse_initial_pose(" 1.5, -2 ,180° ") == pytest.approx((1.5, -2.0, -math.pi))
    assert parse_initial_sigma("0.25,5") == pytest.approx((0.25, math.radians(5)))


def test_a_bad_map_fails_before_anything_is_written(world, tmp_path) -> None:
    log = world[0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    out = tmp_path / "r"
    with pytest.raises(MapFileError, match=r"nowhere\.pgm"):
        localize_log(log, bad, results_dir=out, localizer=double.factory())
    bad.write_text("image: map.pgm\nresolution: 0\norigin: [0, 0, 0]\n")
    with pytest.raises(MapError, match=r"bad\.yaml:2: 'resolution'"):
        localize_log(log, bad, results_dir=out, localizer=double.factory())
    assert not out.exists()


def test_ctrl_c_keeps_the_scans_done(world, tmp_path) -> None:
    log, yaml_path, _ = world
    make = double.factory(searching=3, fail_at={12: KeyboardInterrupt()})
    with pytest.raises(KeyboardInterrupt) as info:
        localize_log(log, yaml_path, results_dir=tmp_path / "r", localizer=make)
    kept = localize_partial(info.value)
    assert kept is not None and kept.scans == 12 and kept.localised
    data = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert data["partial"] is True and data["partial_reason"] == "interrupted at scan 13"
    t, _ = read_tum(tmp_path / "r" / "trajectory.tum")
    assert len(t) == 9 and "part of the" in (tmp_path / "r" / "trajectory.tum").read_text()
    assert not (tmp_path / "r" / ".fuzzypos.lock").exists()  # the lock went with the job


@pytest.mark.parametrize(
    ("settings", "why"),
    [
        ({"fail_at": {9: RuntimeError("the matcher broke")}}, "the matcher broke"),
        ({"broken_at": (9,)}, "is tracking but gives no pose or no covariance"),
    ],
)
def test_an_error_in_the_loop_keeps_the_scans_before_it(world, tmp_path, settings, why) -> None:
    log, yaml_path, _ = world
    with pytest.raises((RuntimeError, ValueError)) as info:
        localize_log(log, yaml_path, results_dir=tmp_path / "r",
                     localizer=double.factory(searching=3, **settings))  # fmt: skip
    kept = localize_partial(info.value)
    assert kept is not None and kept.scans == 9 and kept.poses.shape == (6, 3)
    reason = kept.summary["partial_reason"]
    assert reason.startswith("failed at scan 10: ") and why in reason


def test_no_scan_before_the_error_keeps_nothing(world, tmp_path) -> None:
    log, yaml_path, _ = world
    with pytest.raises(RuntimeError):
        localize_log(log, yaml_path, results_dir=tmp_path / "r",
                     localizer=double.factory(fail_at={0: RuntimeError("at once")}))  # fmt: skip
    assert not (tmp_path / "r").exists()


def test_a_results_folder_of_another_job_is_refused_unless_overwritten(world, tmp_path) -> None:
    log, yaml_path, _ = world
    out = tmp_path / "r"
    localize_log(log, yaml_path, results_dir=out, localizer=double.factory(), max_scans=4)
    with pytest.raises(ResultsFolderError, match="holds the results of another run"):
        localize_log(log, yaml_path, results_dir=out, localizer=double.factory(), max_scans=4)
    s = localize_log(log, yaml_path, results_dir=out, localizer=double.factory(searching=None),
                     max_scans=6, overwrite=True)  # fmt: skip
    assert json.loads((out / "summary.json").read_text())["scans"] == s.scans == 6


def _read_bag(path: Path) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    with AnyReader([path]) as r:
        for conn, _, raw in r.messages():
            out.setdefault(conn.topic, []).append(r.deserialize(raw, conn.msgtype))
    return out


def _yaw(q: Any) -> float:
    return 2.0 * math.atan2(q.z, q.w)


@pytest.mark.parametrize("name", ["out.bag", "out_ros2"])
def test_the_bag_has_amcls_pose_and_map_to_odom(world, tmp_path, name) -> None:
    log, yaml_path, _ = world
    bag = tmp_path / name
    make = double.factory(searching=4, lost=range(10, 12))
    s = localize_log(log, yaml_path, results_dir=tmp_path / "r", bag_out=bag, localizer=make,
                     max_scans=20)  # fmt: skip
    msgs = _read_bag(bag)
    assert sorted(msgs) == sorted([AMCL_POSE_TOPIC, "/tf"])
    poses, tfs = msgs[AMCL_POSE_TOPIC], msgs["/tf"]
    assert len(poses) == len(tfs) == len(s.stamps) == 14
    odom = {rec.scan.stamp: rec.odometry for rec in open_log(log).records()}
    for k, (p, tf) in enumerate(zip(poses, tfs)):
        stamp = p.header.stamp.sec + 1e-9 * p.header.stamp.nanosec
        assert stamp == pytest.approx(s.stamps[k], abs=1e-9) and p.header.frame_id == "map"
        got = (p.pose.pose.position.x, p.pose.pose.position.y, _yaw(p.pose.pose.orientation))
        np.testing.assert_allclose(got[:2], s.poses[k, :2], atol=1e-12)
        cov = np.asarray(p.pose.covariance).reshape(6, 6)[np.ix_((0, 1, 5), (0, 1, 5))]
        assert not np.allclose(cov, 0.0)
        (t,) = tf.transforms
        assert (t.header.frame_id, t.child_frame_id) == ("map", "odom")
        corr = (t.transform.translation.x, t.transform.translation.y, _yaw(t.transform.rotation))
        o = odom[s.stamps[k]]
        again = compose(np.array(corr), np.array([o.x, o.y, o.theta]))  # map→odom∘odom→base
        np.testing.assert_allclose(again[:2], s.poses[k, :2], atol=1e-9)
        assert math.cos(again[2] - s.poses[k, 2]) == pytest.approx(1.0, abs=1e-12)
    data = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert data["bag_out"]["topics"] == {AMCL_POSE_TOPIC: 14, "/tf": 14}
    assert data["files"]["bag"] == str(bag)


def test_the_map_may_be_given_read(world, tmp_path) -> None:
    log, yaml_path, _ = world
    m = read_map_yaml(yaml_path)
    make = double.factory()
    localize_log(log, m, results_dir=tmp_path / "r", localizer=make, max_scans=2)
    assert make.made[0].occupancy_map is m


def test_the_bag_writer_without_odometry_topic_or_transform(tmp_path) -> None:
    """What ``--bag-out`` relies on: a writer with no odometry topic (``topic=None``, whose
    :meth:`write` is refused) and a pose without the scan's odometry: no map → odom."""
    from fuzzypos.io import OdometryBagWriter

    path = tmp_path / "b.bag"
    w = OdometryBagWriter(path, topic=None, pose_topic=AMCL_POSE_TOPIC)
    cov = double.covariance_of(1)
    with pytest.raises(ValueError, match="no odometry topic"):
        w.write(1.0, (0.0, 0.0, 0.0), cov)
    w.write_optimised(1.0, (1.0, 2.0, 0.5), None, cov)
    w.write_optimised(2.0, (1.5, 2.0, 0.0), (0.5, 0.0, 0.0), cov)
    w.close()
    assert (w.optimised_written, w.transforms_written) == (2, 1)
    msgs = _read_bag(path)
    assert sorted(msgs) == sorted([AMCL_POSE_TOPIC, "/tf"])
    assert len(msgs[AMCL_POSE_TOPIC]) == 2 and len(msgs["/tf"]) == 1
    (t,) = msgs["/tf"][0].transforms
    assert t.header.stamp.sec == 2 and t.transform.translation.x == pytest.approx(1.0)


def test_a_pose_the_localizer_refuses_fails_before_anything_is_written(world, tmp_path) -> None:
    """The localizer's own refusal (``InitialPoseError``: a pose in a wall) comes before the
    results folder."""
    log, yaml_path, _ = world

    class Refused(FuzzyposError, ValueError):
        pass

    def refusing(occupancy_map: Any, config: Any = None, **kw: Any) -> Any:
        raise Refused(f"initial pose {kw['initial_pose']} lies in a wall")

    out = tmp_path / "r"
    with pytest.raises(Refused, match="lies in a wall"):
        localize_log(log, yaml_path, results_dir=out, localizer=refusing,
                     initial_pose=(0.0, 4.99, 0.0))  # fmt: skip
    assert not out.exists()
