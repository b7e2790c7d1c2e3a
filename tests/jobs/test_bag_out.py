"""The estimate with its covariance, out: OdometryBagWriter (ROS1, ROS2 sqlite3 and mcap, read
back with rosbags' AnyReader), covariance.csv and ``fuzzypos run --bag-out``."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from typer.testing import CliRunner

import fuzzypos.jobs.run as run_module
from fuzzypos.cli import app
from fuzzypos.geometry import Pose2D, covariance_to_parent, propagate
from fuzzypos.io import BagWriteError, OdometryBagWriter, covariance6, open_log, read_tum
from fuzzypos.io.bag_info import OutputFrames
from fuzzypos.io.rosbag_write import UNUSED_VARIANCE, bag_storage_for
from fuzzypos.jobs import run_log
from fuzzypos.jobs.outputs import COVARIANCE_COLUMNS
from fuzzypos.jobs.sinks import BagSink, CovarianceSink, PoseCovariances, ScanResult, Track
from fuzzypos.pipeline import Positioner
from helpers import write_sim_log

runner = CliRunner()
KINDS = {"ros1": "out.bag", "sqlite3": "out_sqlite", "mcap": "out_mcap"}
COV = np.diag([1e-6, 1e-6, 1e-8])


def _yaw(q: Any) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def _read(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """topic → [(record time ns, message)], in the bag's order."""
    out: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([path]) as r:
        for conn, t, raw in r.messages():
            out.setdefault(conn.topic, []).append((t, r.deserialize(raw, conn.msgtype)))
    return out


def _known():
    """(stamp, pose, pose_cov3, twist, twist_cov3) rows with every entry distinct."""
    rows = []
    for k in range(5):
        c = np.array([[1.0, 0.2, 0.03], [0.2, 2.0, -0.04], [0.03, -0.04, 0.05]]) * 1e-4 * (k + 1)
        tc = None if k == 0 else c * 100
        rows.append(
            (1.7e9 + 0.25 * k + 0.000123, (0.5 * k, -0.3 * k, 3.0 - 1.4 * k), c, (0.2, -0.1, k), tc)
        )
    return rows


# -- the writer --------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_writer_round_trip(tmp_path, kind):
    path = tmp_path / KINDS[kind]
    rows = _known()
    with OdometryBagWriter(path, storage=kind) as w:
        for row in rows:
            w.write(*row)
    assert w.written == len(rows)
    if kind == "ros1":
        assert path.is_file() and path.read_bytes().startswith(b"#ROSBAG V2.0")
    else:
        assert (path / "metadata.yaml").is_file()
        suffix = ".mcap" if kind == "mcap" else ".db3"
        assert [p.suffix for p in path.iterdir() if p.name != "metadata.yaml"] == [suffix]
        assert f"storage_identifier: {kind}" in (path / "metadata.yaml").read_text()
    msgs = _read(path)
    assert set(msgs) == {"/fuzzypos/odom", "/tf"}
    odom, tf = msgs["/fuzzypos/odom"], msgs["/tf"]
    assert len(odom) == len(tf) == len(rows)
    for (t, m), (t_tf, tfm), (stamp, pose, pc, twist, tc) in zip(odom, tf, rows):
        # stamps: header and record time, to the nanosecond
        assert t == t_tf == m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        assert abs(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 - stamp) < 1e-6
        assert m.header.stamp.nanosec == round((stamp - math.floor(stamp)) * 1e9)
        assert (m.header.frame_id, m.child_frame_id) == ("odom", "base_link")
        p = m.pose.pose
        assert (p.position.x, p.position.y, p.position.z) == (pose[0], pose[1], 0.0)
        assert math.remainder(_yaw(p.orientation) - pose[2], 2 * math.pi) == pytest.approx(
            0.0, abs=1e-12
        )
        assert (p.orientation.x, p.orientation.y) == (0.0, 0.0)
        # 6x6 row-major: x, y, yaw from the 3x3, z/roll/pitch 1e6 on the diagonal, else 0
        c6 = np.asarray(m.pose.covariance).reshape(6, 6)
        assert c6.shape == (6, 6)
        np.testing.assert_array_equal(c6[np.ix_([0, 1, 5], [0, 1, 5])], pc)
        assert c6[0, 5] == pc[0, 2] and c6[5, 1] == pc[2, 1]  # yaw is the last row/column
        np.testing.assert_array_equal(np.diag(c6)[2:5], [UNUSED_VARIANCE] * 3)
        mask = np.ones((6, 6), bool)
        mask[np.ix_([0, 1, 5], [0, 1, 5])] = False
        mask[[2, 3, 4], [2, 3, 4]] = False
        assert not c6[mask].any()
        tw = m.twist.twist
        assert (tw.linear.x, tw.linear.y, tw.linear.z) == (twist[0], twist[1], 0.0)
        assert (tw.angular.x, tw.angular.y, tw.angular.z) == (0.0, 0.0, twist[2])
        t6 = np.asarray(m.twist.covariance).reshape(6, 6)
        if tc is None:
            np.testing.assert_array_equal(t6, np.eye(6) * UNUSED_VARIANCE)
        else:
            np.testing.assert_array_equal(t6[np.ix_([0, 1, 5], [0, 1, 5])], tc)
        # tf: one odom -> base_link transform, the same pose and stamp
        (tr,) = tfm.transforms
        assert (tr.header.frame_id, tr.child_frame_id) == ("odom", "base_link")
        assert tr.header.stamp.sec == m.header.stamp.sec
        assert tr.header.stamp.nanosec == m.header.stamp.nanosec
        v = tr.transform.translation
        assert (v.x, v.y, v.z) == (pose[0], pose[1], 0.0)
        assert tr.transform.rotation.z == p.orientation.z
        assert tr.transform.rotation.w == p.orientation.w


def test_covariance6_layout():
    c3 = np.arange(9.0).reshape(3, 3)
    c6 = covariance6(c3).reshape(6, 6)
    assert covariance6(c3).shape == (36,)
    assert c6[0, 0] == 0 and c6[0, 1] == 1 and c6[0, 5] == 2
    assert c6[1, 0] == 3 and c6[1, 1] == 4 and c6[1, 5] == 5
    assert c6[5, 0] == 6 and c6[5, 1] == 7 and c6[5, 5] == 8
    assert c6[2, 2] == c6[3, 3] == c6[4, 4] == 1e6
    np.testing.assert_array_equal(covariance6(None), np.eye(6).reshape(36) * 1e6)


def test_storage_by_name_and_by_flag():
    assert bag_storage_for("a/run.bag") == "ros1"
    assert bag_storage_for("a/RUN.BAG") == "ros1"
    assert bag_storage_for("a/run") == "sqlite3"
    assert bag_storage_for("a/run.bag", "mcap") == "mcap"
    with pytest.raises(ValueError, match="ros1, sqlite3, mcap"):
        bag_storage_for("x", "zip")


@pytest.mark.parametrize("kind", KINDS)
def test_an_existing_path_is_never_overwritten(tmp_path, kind):
    path = tmp_path / KINDS[kind]
    if kind == "ros1":
        path.write_text("mine")
    else:
        path.mkdir()
        (path / "keep").write_text("mine")
    with pytest.raises(FileExistsError, match="never overwritten") as info:
        OdometryBagWriter(path, kind)
    assert info.value.filename == str(path)
    assert (path if kind == "ros1" else path / "keep").read_text() == "mine"


@pytest.mark.parametrize(
    ("args", "what"),
    [
        ((-1.0, (0, 0, 0), COV), "stamp"),
        ((math.nan, (0, 0, 0), COV), "stamp"),
        ((1.0, (0, math.inf, 0), COV), "pose"),
        ((1.0, (0, 0), COV), "pose"),
        ((1.0, (0, 0, 0), np.eye(2)), "pose covariance"),
        ((1.0, (0, 0, 0), None), "pose covariance is missing"),
        ((1.0, (0, 0, 0), np.array([[1, 2, 0], [0, 1, 0], [0, 0, 1.0]])), "symmetric"),
        ((1.0, (0, 0, 0), -COV), "non-negative"),
        ((1.0, (0, 0, 0), COV, (0, 0, 0), np.full((3, 3), np.nan)), "twist covariance"),
    ],
)
def test_bad_values_name_the_bag_and_the_message(tmp_path, args, what):
    path = tmp_path / "bad_bag"
    with OdometryBagWriter(path) as w:
        w.write(0.5, Pose2D(1, 2, 3), COV)
        with pytest.raises(BagWriteError, match=f"^{path}:2: .*{what}"):
            w.write(*args)
        w.write(0.6, (1, 2, 3), COV)
    assert len(_read(path)["/fuzzypos/odom"]) == 2
    with pytest.raises(ValueError, match="closed"):
        w.write(0.7, (1, 2, 3), COV)


@pytest.mark.parametrize("kind", KINDS)
def test_abort_leaves_no_bag(tmp_path, kind):
    path = tmp_path / KINDS[kind]
    with pytest.raises(RuntimeError), OdometryBagWriter(path, kind) as w:
        w.write(0.5, (1, 2, 3), COV)
        raise RuntimeError("stop")
    assert not path.exists()


# -- the run job ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "sim.clf"
    write_sim_log(path)
    return path


def _cov_of(k: int) -> np.ndarray:
    """A covariance per scan, different at each (the positioner's is not filled yet)."""
    c = COV * (1.0 + 0.5 * k)
    c[0, 1] = c[1, 0] = 2e-7
    c[1, 2] = c[2, 1] = -1e-8
    return c


def _positioner_with(covariance):
    """A Positioner whose estimates carry ``covariance(k)``, recording them."""

    class WithCovariance(Positioner):
        estimates: ClassVar[list] = []

        def update(self, scan, odom=None):
            est = super().update(scan, odom)
            est = dataclasses.replace(est, covariance=covariance(len(self.estimates)))
            self.estimates.append(est)
            return est

    return WithCovariance


def _odometry_checks(msgs, tum_path: Path, estimates) -> None:
    stamps, poses = read_tum(tum_path)
    odom = [m for _, m in msgs["/fuzzypos/odom"]]
    assert len(odom) == len(stamps) == len(estimates) == len(msgs["/tf"])
    got = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in odom])
    np.testing.assert_allclose(got, poses[:, :2], atol=1e-9, rtol=0)
    yaw = np.array([_yaw(m.pose.pose.orientation) for m in odom])
    np.testing.assert_allclose(
        np.remainder(yaw - poses[:, 2] + np.pi, 2 * np.pi) - np.pi, 0, atol=1e-9
    )
    t = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in odom])
    np.testing.assert_allclose(t, stamps, atol=1e-9, rtol=0)
    # the running covariance: the first estimate's, then propagated, in the odom frame
    cov = estimates[0].covariance
    for k, (est, m) in enumerate(zip(estimates, odom)):
        if k:
            cov = propagate(cov, est.increment.as_array(), est.covariance)
        c6 = np.asarray(m.pose.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])]
        np.testing.assert_allclose(c6, covariance_to_parent(est.pose.as_array(), cov), rtol=1e-12)
    assert np.asarray(odom[-1].pose.covariance)[0] > 10 * estimates[0].covariance[0, 0]
    # the twist: zero with unknown covariance first, then the increment over dt
    assert odom[0].twist.twist.linear.x == 0.0
    np.testing.assert_array_equal(odom[0].twist.covariance, np.eye(6).reshape(36) * 1e6)
    for k in range(1, len(odom)):
        dt = estimates[k].stamp - estimates[k - 1].stamp
        inc = estimates[k].increment
        tw = odom[k].twist
        assert (tw.twist.linear.x, tw.twist.linear.y) == pytest.approx((inc.x / dt, inc.y / dt))
        assert tw.twist.angular.z == pytest.approx(inc.theta / dt)
        t3 = np.asarray(tw.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])]
        np.testing.assert_allclose(t3, estimates[k].covariance / dt**2, rtol=1e-12)


def _covariance_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_run_log_writes_the_bag_and_covariance_csv(sim_log, tmp_path, monkeypatch, kind):
    cls = _positioner_with(_cov_of)
    monkeypatch.setattr(run_module, "Positioner", cls)
    out, bag = tmp_path / "res", tmp_path / KINDS[kind]
    storage = None if kind != "mcap" else "mcap"
    res = run_log(open_log(sim_log), results_dir=out, plot=False, bag_out=bag, bag_storage=storage)
    assert res.files["bag"] == bag and res.files["covariance.csv"] == out / "covariance.csv"
    assert not list(out.glob(".*"))
    _odometry_checks(_read(bag), out / "trajectory.tum", cls.estimates)
    header, rows = _covariance_rows(out / "covariance.csv")
    assert header == list(COVARIANCE_COLUMNS)
    assert header[:7] == ["stamp", "xx", "xy", "xtheta", "yy", "ytheta", "thetatheta"]
    stamps, _ = read_tum(out / "trajectory.tum")
    assert len(rows) == res.scans == len(stamps)
    assert [float(r[0]) for r in rows] == stamps.tolist()
    for k, r in enumerate(rows):
        c = _cov_of(k)
        assert [float(v) for v in r[1:7]] == [c[0, 0], c[0, 1], c[0, 2], c[1, 1], c[1, 2], c[2, 2]]


def test_run_log_without_covariance(sim_log, tmp_path, monkeypatch):
    """No covariance from the positioner: no covariance.csv (a note says so), and a bag asked
    for is a ValueError naming the first scan, leaving neither bag nor partial files."""
    out = tmp_path / "res"
    run_log(open_log(sim_log), results_dir=out, plot=False)  # an earlier run's covariance.csv
    assert (out / "covariance.csv").is_file()
    monkeypatch.setattr(run_module, "Positioner", _positioner_with(lambda k: None))
    res = run_log(open_log(sim_log), results_dir=out, plot=False, overwrite=True)
    assert "covariance.csv" not in res.files and not (out / "covariance.csv").exists()
    assert any("no covariance" in n for n in res.notes)
    bag = tmp_path / "b.bag"
    out2 = tmp_path / "res2"
    with pytest.raises(ValueError, match=r"sim\.clf: scan 1 \(stamp 0\.0\): .*no covariance"):
        run_log(open_log(sim_log), results_dir=out2, plot=False, bag_out=bag)
    assert not bag.exists() and not out2.exists()


def test_a_covariance_missing_mid_run_names_the_scan(sim_log, tmp_path, monkeypatch):
    monkeypatch.setattr(
        run_module, "Positioner", _positioner_with(lambda k: None if k == 4 else COV)
    )
    out = tmp_path / "res"
    with pytest.raises(ValueError, match=r"scan 5 \(stamp 0\.4\): the estimate has no covariance"):
        run_log(open_log(sim_log), results_dir=out, plot=False)
    _header, rows = _covariance_rows(out / "covariance.csv")  # the 4 scans before it are kept
    assert len(rows) == 4 and len(read_tum(out / "trajectory.tum")[0]) == 4
    monkeypatch.setattr(run_module, "Positioner", _positioner_with(lambda k: np.eye(2)))
    with pytest.raises(ValueError, match=r"scan 1 .*finite 3x3"):
        run_log(open_log(sim_log), results_dir=tmp_path / "res2", plot=False)
    assert not (tmp_path / "res2").exists()


def test_the_bag_glue_on_known_estimates(tmp_path):
    """Estimates built by hand: the first pose's covariance (turned by 90° into odom), the
    covariance carried along a straight metre, a zero time step's unknown twist."""
    from fuzzypos.pipeline import Estimate

    c0 = np.diag([4e-6, 1e-6, 1e-8])
    ident = Pose2D()
    ests = [
        Estimate(0.0, Pose2D(0, 0, math.pi / 2), ident, ident, 0, False, covariance=c0),
        Estimate(0.5, Pose2D(0, 1, math.pi / 2), Pose2D(1, 0, 0), ident, 3, False, covariance=COV),
        Estimate(0.5, Pose2D(0, 1, math.pi / 2), ident, ident, 0, False, covariance=COV),
    ]
    bag = tmp_path / "glue.bag"
    covariances = PoseCovariances("hand")
    track = Track("hand")
    sinks = [
        CovarianceSink(tmp_path, "hand", required=True),
        BagSink(bag, None, OutputFrames(), track, "hand"),
    ]
    for sink in sinks:
        sink.open()
    for k, est in enumerate(ests):
        result = ScanResult(k, None, est, covariances.of(k, est))
        for sink in sinks:
            sink.write(result)
    assert {**sinks[0].close(partial=False), **sinks[1].close(partial=False)} == {
        "covariance.csv": tmp_path / "covariance.csv",
        "bag": bag,
    }
    odom = [m for _, m in _read(bag)["/fuzzypos/odom"]]
    block = [
        np.asarray(m.pose.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])] for m in odom
    ]
    np.testing.assert_allclose(block[0], np.diag([1e-6, 4e-6, 1e-8]), rtol=1e-12, atol=1e-20)
    # one metre ahead (odom +y): the heading's variance adds d²·σθ² sideways (odom x), the
    # position's along; x and yaw correlate negatively (turning left moves the robot to -x)
    expected = np.array([[1e-6 + 1e-8 + 1e-6, 0, -1e-8], [0, 4e-6 + 1e-6, 0], [-1e-8, 0, 2e-8]])
    np.testing.assert_allclose(block[1], expected, rtol=1e-9, atol=1e-20)
    assert odom[1].twist.twist.linear.x == pytest.approx(2.0)
    np.testing.assert_allclose(
        np.asarray(odom[1].twist.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])], COV * 4
    )
    assert odom[2].twist.twist.linear.x == 0.0  # dt = 0
    np.testing.assert_array_equal(odom[2].twist.covariance, np.eye(6).reshape(36) * 1e6)


# -- the command line ---------------------------------------------------------------------
def test_cli_refuses_an_existing_bag(sim_log, tmp_path):
    bag = tmp_path / "there.bag"
    bag.write_bytes(b"mine")
    r = runner.invoke(
        app, ["run", str(sim_log), "--results", str(tmp_path / "r"), "--bag-out", str(bag)]
    )
    assert r.exit_code == 2
    err = r.stderr.strip()
    assert err.count("\n") == 0 and str(bag) in err and "never overwritten" in err
    assert bag.read_bytes() == b"mine"
    r = runner.invoke(
        app,
        [
            "run",
            str(sim_log),
            "--results",
            str(tmp_path / "r"),
            "--bag-out",
            str(tmp_path / "x"),
            "--bag-storage",
            "zip",
        ],
    )
    assert r.exit_code == 2 and "bag storage must be one of" in r.stderr
    assert not (tmp_path / "x").exists()


def _first_covariance(path: Path):
    rec = next(iter(open_log(path).records()))
    return Positioner().update(rec.scan, rec.odometry).covariance


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_cli_run_with_bag_out_end_to_end(sim_log, tmp_path, kind):
    if _first_covariance(sim_log) is None:
        pytest.skip("Estimate.covariance not filled yet")
    out, bag = tmp_path / "res", tmp_path / KINDS[kind]
    args = ["run", str(sim_log), "--results", str(out), "--bag-out", str(bag)]
    if kind == "mcap":
        args += ["--bag-storage", "mcap"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    assert f"odometry bag in {bag}" in r.output
    msgs = _read(bag)
    stamps, poses = read_tum(out / "trajectory.tum")
    odom = [m for _, m in msgs["/fuzzypos/odom"]]
    assert len(odom) == len(msgs["/tf"]) == len(stamps)
    got = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in odom])
    np.testing.assert_allclose(got, poses[:, :2], atol=1e-9, rtol=0)
    yaw = np.array([_yaw(m.pose.pose.orientation) for m in odom])
    np.testing.assert_allclose(
        np.remainder(yaw - poses[:, 2] + np.pi, 2 * np.pi) - np.pi, 0, atol=1e-9
    )
    header, rows = _covariance_rows(out / "covariance.csv")
    assert header == list(COVARIANCE_COLUMNS) and len(rows) == len(stamps)
    assert [float(r[0]) for r in rows] == stamps.tolist()
    c6 = np.asarray(odom[-1].pose.covariance).reshape(6, 6)
    assert np.all(np.linalg.eigvalsh(c6) > 0)
    # the pose covariance grows along the run, as propagation must make it
    first = np.asarray(odom[0].pose.covariance).reshape(6, 6)
    assert np.trace(c6[:2, :2]) > np.trace(first[:2, :2])
