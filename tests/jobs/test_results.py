"""The run job and its results folder (fuzzypos.jobs.run), scoring trajectory files
(fuzzypos.eval.scoring), provenance (fuzzypos.io.provenance), the benchmark
(fuzzypos.jobs.benchmark), and the deprecated paths fuzzypos.logs and fuzzypos.evaluation."""

from __future__ import annotations

import hashlib
import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from fuzzypos.config import Config
from fuzzypos.eval import evaluate_trajectory
from fuzzypos.geometry import Pose2D
from fuzzypos.io import CarmenReader, CarmenWriter, LogRecord, open_log, read_tum
from fuzzypos.io.provenance import file_sha256, git_hash
from fuzzypos.jobs import (
    ResultsFolderError,
    log_name,
    partial_results,
    run_benchmark,
    run_log,
    write_estimate_clf,
)
from fuzzypos.jobs.benchmark import BENCHMARK_CONFIGS, find_benchmark_logs
from fuzzypos.scan import LaserScan
from helpers import write_relations, write_sim_log

FILES = {"trajectory.tum", "trajectory.clf", "config.toml", "path.png", "summary.json"}


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim")
    path = d / "sim.clf"
    run = write_sim_log(path)
    return path, run


# -- run_log -----------------------------------------------------------------------------------
def test_run_log_writes_every_file_and_they_parse(sim_log, tmp_path):
    path, run = sim_log
    cfg = Config.preset("paper")
    out = tmp_path / "res"
    extra = tmp_path / "copy.tum"
    res = run_log(open_log(path), cfg, results_dir=out, out_tum=extra, preset="paper")
    assert {p.name for p in out.iterdir()} >= FILES
    assert not list(out.glob(".*tmp"))
    n = len(run)
    assert res.scans == n and res.poses.shape == (n, 3)

    # trajectory.tum: one pose per scan, the log's stamps exactly, in file order
    stamps, poses = read_tum(out / "trajectory.tum")
    assert stamps.tolist() == list(run.stamps)
    np.testing.assert_allclose(poses, res.poses, atol=1e-12)
    assert read_tum(extra)[0].tolist() == stamps.tolist()

    # config.toml loads back as the config used
    assert Config.from_toml(out / "config.toml") == cfg

    # summary.json
    s = json.loads((out / "summary.json").read_text())
    for key in (
        "fuzzypos_version",
        "git_hash",
        "input",
        "scans",
        "scans_degraded",
        "odometry_jumps_rejected",
        "seconds",
        "scans_per_second",
        "config",
        "bad_lines_skipped",
        "truth_errors",
        "positioner_ms_per_scan",
        "notes",
    ):
        assert key in s, key
    assert s["scans"] == n and s["config"]["preset"] == "paper"
    assert s["input"]["kind"] == "carmen"
    assert s["input"]["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert s["scans_per_second"] > 0 and s["bad_lines_skipped"] == 0
    est = s["truth_errors"]["estimate"]
    assert est["mean_position_error_m"] >= 0  # accuracy is the positioner tests' business
    assert "odometry" in s["truth_errors"]

    # trajectory.clf: FLASER x y θ = the estimate, odom = the log's odometry, truth kept
    back = list(CarmenReader(out / "trajectory.clf").records())
    assert len(back) == n
    for k, rec in enumerate(back):
        assert rec.scan.stamp == run.stamps[k]
        assert rec.odometry == run.odometry_pose(k)
        assert rec.truth == run.true_pose(k)
        np.testing.assert_array_equal(rec.scan.valid, run.scans[k].valid)
        np.testing.assert_allclose(
            rec.scan.ranges[rec.scan.valid], run.scans[k].ranges[run.scans[k].valid], atol=6e-5
        )
    flaser = [
        ln.split()
        for ln in (out / "trajectory.clf").read_text().splitlines()
        if ln.startswith("FLASER")
    ]
    nb = int(flaser[0][1])
    xyz = np.array([[float(v) for v in f[2 + nb : 5 + nb]] for f in flaser])
    np.testing.assert_array_equal(xyz, res.poses)


def test_run_log_with_a_stretch(sim_log, tmp_path):
    path, run = sim_log
    res = run_log(path, Config(), results_dir=tmp_path / "a", start=1.0, max_scans=5, plot=False)
    first = next(k for k, t in enumerate(run.stamps) if t - run.stamps[0] >= 1.0)
    assert res.scans == 5 and res.stamps.tolist() == list(run.stamps[first : first + 5])
    assert "path.png" not in res.files
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["selection"] == {"start_s": 1.0, "end_s": None, "max_scans": 5}
    with pytest.raises(ValueError, match="holds no scans: the log's 32 scans run from"):
        run_log(path, Config(), results_dir=tmp_path / "b", start=1e6)
    assert not (tmp_path / "b" / "trajectory.clf").exists()


def test_run_log_on_an_empty_log_is_an_error(tmp_path):
    p = tmp_path / "empty.clf"
    p.write_text("# nothing\n")
    with pytest.raises(ValueError, match="no scans"):
        run_log(p, results_dir=tmp_path / "r")


def test_a_failure_mid_log_keeps_the_scans_before_it_marked_partial(sim_log, tmp_path):
    path, run = sim_log
    lines = path.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("FLASER")) + 10
    bad = tmp_path / "bad.clf"
    bad.write_text("".join([*lines[:k], "FLASER 3 1 2\n", *lines[k:]]))
    out = tmp_path / "res"
    with pytest.raises(ValueError, match="FLASER") as info:
        run_log(bad, results_dir=out, out_tum=tmp_path / "x.tum")
    kept = partial_results(info.value)
    # the reader holds scan 5 for its TRUEPOS when the bad line stops it
    assert kept is not None and kept.results_dir == out and kept.scans == 4
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] is True and s["scans"] == 4
    assert (
        s["partial_reason"].startswith("failed at scan 5: ") and "bad.clf:" in s["partial_reason"]
    )
    stamps, _ = read_tum(out / "trajectory.tum")
    assert stamps.tolist() == list(run.stamps[:4])
    assert [r.scan.stamp for r in CarmenReader(out / "trajectory.clf").records()] == stamps.tolist()
    assert Config.from_toml(out / "config.toml") == Config()
    assert not (out / "path.png").exists() and not (tmp_path / "x.tum").exists()
    assert not list(out.glob(".*"))
    # the next run into the folder is refused, or replaces it whole with overwrite=True
    with pytest.raises(ResultsFolderError, match="holds the results of another run"):
        run_log(open_log(bad, skip_bad_lines=True), results_dir=out, plot=False)
    res = run_log(open_log(bad, skip_bad_lines=True), results_dir=out, plot=False, overwrite=True)
    assert res.summary["bad_lines_skipped"] == 1 and res.summary["partial"] is False
    assert json.loads((out / "summary.json").read_text())["partial_reason"] is None
    assert partial_results(ValueError("x")) is None


def test_a_failure_at_the_first_scan_keeps_nothing(tmp_path):
    bad = tmp_path / "bad.clf"
    bad.write_text("FLASER 3 1 2\n")
    out = tmp_path / "new" / "res"
    with pytest.raises(ValueError, match="FLASER") as info:
        run_log(bad, results_dir=out)
    assert partial_results(info.value) is None
    assert not (tmp_path / "new").exists()  # no empty folder left behind


def test_run_log_rejects_bad_arguments(sim_log, tmp_path):
    path, _ = sim_log
    with pytest.raises(ValueError, match="map_every"):
        run_log(path, results_dir=tmp_path, map_every=0)
    with pytest.raises(ValueError, match="max_scans"):
        run_log(path, results_dir=tmp_path, max_scans=-1)


def test_progress_is_reported(sim_log, tmp_path):
    path, run = sim_log
    calls: list[tuple[int, int | None]] = []
    run_log(path, results_dir=tmp_path, progress=lambda d, t: calls.append((d, t)), plot=False)
    assert calls[-1] == (len(run), len(run)) and calls[0][1] == len(run)


def test_the_progress_total_of_a_stretch_is_the_stretch(sim_log, tmp_path):
    """--start/--end: the total is the scans of the stretch, not of the whole log."""
    path, run = sim_log
    calls: list[tuple[int, int | None]] = []
    res = run_log(
        path,
        results_dir=tmp_path / "a",
        progress=lambda d, t: calls.append((d, t)),
        start=0.3,
        end=2.9,
        plot=False,
    )
    assert 25 <= res.scans < len(run)
    assert [t for _, t in calls] == [res.scans] * len(calls) and calls[-1][0] == res.scans
    calls.clear()
    run_log(
        path,
        results_dir=tmp_path / "b",
        progress=lambda d, t: calls.append((d, t)),
        start=0.3,
        max_scans=3,
        plot=False,
    )
    assert calls == [(3, 3)]


def test_ctrl_c_keeps_the_scans_done_marked_partial(sim_log, tmp_path):
    path, run = sim_log
    out = tmp_path / "res"

    def stop(done: int, total: int | None) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as info:
        run_log(path, results_dir=out, progress=stop)
    kept = partial_results(info.value)
    assert kept is not None and kept.scans == 25 and kept.summary["partial"] is True
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] is True and s["partial_reason"] == "interrupted at scan 26"
    assert s["scans"] == 25 and s["last_stamp"] == run.stamps[24]
    assert read_tum(out / "trajectory.tum")[0].tolist() == list(run.stamps[:25])
    assert len(list(CarmenReader(out / "trajectory.clf").records())) == 25
    assert len((out / "covariance.csv").read_text().splitlines()) == 26  # header + 25
    assert not (out / "path.png").exists() and not list(out.glob(".*"))


# -- the estimate as CARMEN ------------------------------------------------------------------
def test_write_estimate_clf_keeps_a_span_geometry_and_a_forward_mount(tmp_path):
    n = 180
    inc = math.pi / (n - 1)  # exactly -90° … +90°, like the aces bag
    mount = Pose2D(0.2, 0.0, 0.0)
    recs = []
    for k in range(4):
        r = np.full(n, 2.0 + 0.1 * k)
        r[3], r[4] = np.nan, 50.0
        scan = LaserScan(
            r, -math.pi / 2, inc, range_max=50.0, stamp=1.0 + 0.001 * k, sensor_pose=mount
        )
        recs.append((scan, Pose2D(k, 0.0, 0.0), None if k == 2 else Pose2D(0, k, 0), None))
    p = tmp_path / "e.clf"
    assert write_estimate_clf(p, recs) == 4
    text = p.read_text()
    assert "convention 'span'" in text and "ROBOTLASER1 99" not in text
    back = list(CarmenReader(p, convention="span").records())
    assert [b.scan.stamp for b in back] == [1.0, 1.001, 1.002, 1.003]
    assert back[0].scan.sensor_pose == mount  # PARAM robot_frontlaser_offset
    np.testing.assert_allclose(back[0].scan.angles, recs[0][0].angles, atol=1e-12)
    assert back[1].odometry == Pose2D(0, 1, 0)
    assert back[2].odometry == Pose2D(2, 0, 0)  # no odometry: the estimate
    assert not back[0].scan.valid[3] and back[0].scan.valid[0]


def _robotlaser_scan(k: int, n: int = 361) -> LaserScan:
    """A 361-beam 180° scan 0.007° off FLASER's angles, on a mount off the robot's x axis."""
    r = np.linspace(1.0, 9.0, n) + 0.01 * k
    r[3], r[4], r[5] = np.nan, 50.0, np.inf
    inc = math.radians(180.007) / (n - 1)
    return LaserScan(
        r,
        -math.pi / 2,
        inc,
        range_max=50.0,
        stamp=7.0 + 0.1 * k,
        sensor_pose=Pose2D(0.12, -0.03, 0.02),
    )


def test_write_estimate_clf_writes_robotlaser1_lines_that_read_back(tmp_path):
    recs = []
    for k in range(3):
        odom = None if k == 1 else Pose2D(0.5 * k, 0.1, 0.05 * k)
        truth = Pose2D(k, 0, 0) if k else None
        recs.append((_robotlaser_scan(k), Pose2D(k, 2.0, -0.1 * k), odom, truth))
    p = tmp_path / "e.clf"
    assert write_estimate_clf(p, recs, source="x.clf") == 3
    kinds = [ln.split()[0] for ln in p.read_text().splitlines() if not ln.startswith("#")]
    assert kinds == [
        "ODOM",
        "ROBOTLASER1",
        "ODOM",
        "ROBOTLASER1",
        "TRUEPOS",
        "ODOM",
        "ROBOTLASER1",
        "TRUEPOS",
    ]
    for mode in ("scan", "interpolated"):
        back = list(CarmenReader(p, odometry=mode).records())
        assert len(back) == 3
        for b, (scan, est, odom, truth) in zip(back, recs):
            assert b.scan.stamp == scan.stamp and b.truth == truth
            assert (b.scan.angle_min, b.scan.angle_increment) == (
                scan.angle_min,
                scan.angle_increment,
            )
            assert b.scan.range_max == scan.range_max
            np.testing.assert_array_equal(b.scan.valid, scan.valid)
            np.testing.assert_allclose(
                b.scan.ranges[scan.valid], scan.ranges[scan.valid], atol=6e-5
            )
            np.testing.assert_allclose(
                b.scan.sensor_pose.as_array(), scan.sensor_pose.as_array(), atol=1e-12
            )
            # the robot pose is the estimate; the log's odometry is in the ODOM line
            want = est if mode == "scan" or odom is None else odom  # FLASER's rule
            np.testing.assert_allclose(b.odometry.as_array(), want.as_array(), atol=1e-12)


def test_write_estimate_clf_mixes_flaser_and_robotlaser1_where_needed(tmp_path):
    """FLASER while the first scan's geometry fits; the scans that do not are ROBOTLASER1."""
    flaser = LaserScan(np.full(180, 3.0), -math.pi / 2, math.pi / 180, stamp=1.0)
    other = LaserScan(np.ones(5), 0.0, 0.1, stamp=2.0)  # not symmetric about the x axis
    p = tmp_path / "x.clf"
    w = CarmenWriter(p, estimate_of="log.clf")
    for scan in (flaser, other, flaser):
        w.write(scan, Pose2D(1, 0, 0), pose=Pose2D(2, 0, 0))
    assert w.close() and (w.written, w.robotlaser1) == (3, 1)
    assert len(w.notes) == 1 and w.notes[0].startswith("x.clf: 1 of 3 scans are ROBOTLASER1")
    kinds = [ln.split()[0] for ln in p.read_text().splitlines() if not ln.startswith("#")]
    assert kinds == ["FLASER", "ODOM", "ROBOTLASER1", "FLASER"]
    back = list(CarmenReader(p).records())
    assert [b.scan.n_beams for b in back] == [180, 5, 180]
    np.testing.assert_allclose(back[1].scan.angles, other.angles, atol=1e-15)


# -- provenance ------------------------------------------------------------------------------
def test_file_sha256_of_a_file_and_of_a_directory(tmp_path):
    f = tmp_path / "a.bin"
    f.write_bytes(b"hello")
    assert file_sha256(f) == hashlib.sha256(b"hello").hexdigest()
    d = tmp_path / "bag"
    (d / "sub").mkdir(parents=True)
    (d / "metadata.yaml").write_text("x")
    (d / "sub" / "b.db3").write_bytes(b"1234")
    h1 = file_sha256(d)
    assert h1 == file_sha256(d) and len(h1) == 64
    (d / "sub" / "b.db3").write_bytes(b"1235")
    assert file_sha256(d) != h1


def test_git_hash_is_this_checkouts_commit():
    """Run from a git checkout (as the tests are), the provenance names its commit."""
    top = Path(__file__).resolve().parents[2]
    done = subprocess.run(["git", "-C", str(top), "rev-parse", "HEAD"], capture_output=True,
                          text=True)  # fmt: skip
    if done.returncode != 0:
        pytest.skip("not a git checkout (a source tarball): no commit to name")
    assert git_hash() == done.stdout.strip()


def test_git_hash_never_fails(monkeypatch):
    h = git_hash()
    assert h is None or (len(h) == 40 and int(h, 16) >= 0)

    def boom(*a, **k):
        raise FileNotFoundError("git")

    monkeypatch.setattr(subprocess, "run", boom)
    assert git_hash() is None


def test_log_name():
    assert log_name("data/intel.clf.gz") == "intel"
    assert log_name("aces.bag") == "aces"
    assert log_name("my_bag/") == "my_bag"
    assert log_name(".clf") == ".clf"
    assert log_name("x.clf.bz2") == "x"


# -- evaluate_trajectory ----------------------------------------------------------------------
def test_evaluate_the_truth_against_itself_is_zero(sim_log, tmp_path):
    _path, run = sim_log
    from fuzzypos.io import write_tum

    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    est = tmp_path / "est.tum"
    write_tum(est, st, truth)
    rel = tmp_path / "r.relations"
    n = len(st)
    write_relations(rel, st, truth, [(k, k + 3) for k in range(0, n - 3, 2)] + [(0, n - 1)])
    ev = evaluate_trajectory(est, relations=rel, reference=est)
    assert ev.relations.all.translation_m.max < 1e-9
    assert ev.relations.all.matched == len(range(0, n - 3, 2)) + 1
    assert ev.ate.rmse_m < 1e-9 and ev.rpe_frame.translation_m.max < 1e-9
    d = ev.as_dict()
    assert d["relations"]["all_trans_mean_m"] < 1e-9 and d["ate"]["rmse_m"] < 1e-9
    json.dumps(d, allow_nan=False)
    # the odometry is not the truth
    odo = tmp_path / "odo.tum"
    write_tum(odo, st, np.asarray(run.odometry_poses))
    assert evaluate_trajectory(odo, relations=rel).relations.all.translation_m.mean > 1e-4
    with pytest.raises(ValueError, match="nothing to evaluate"):
        evaluate_trajectory(est)


# -- the benchmark ---------------------------------------------------------------------------
def test_find_benchmark_logs(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.relations").write_text("")
    (tmp_path / "a" / "x.clf.gz").write_bytes(b"")
    (tmp_path / "a" / "x.bag").write_bytes(b"")
    (tmp_path / "a" / "y.clf").write_text("")  # no relations
    found = find_benchmark_logs(tmp_path)
    assert [p.name for p, _ in found] == ["x.clf.gz", "x.bag"]
    with pytest.raises(FileNotFoundError):
        find_benchmark_logs(tmp_path / "missing")


def test_run_benchmark_on_a_simulated_log(sim_log, tmp_path):
    path, run = sim_log
    data = tmp_path / "data" / "sim"
    data.mkdir(parents=True)
    (data / "sim.clf").write_bytes(path.read_bytes())
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    write_relations(data / "sim.relations", st, truth, [(k, k + 2) for k in range(len(st) - 2)])
    out = tmp_path / "bench"
    res = run_benchmark(tmp_path / "data", out, plot=False, loop_closure=False)
    assert [(r["log"], r["config"]) for r in res.rows] == [
        ("sim.clf", "odometry"),
        ("sim.clf", "paper"),
        ("sim.clf", "default"),
    ]
    for r in res.rows:
        assert "error" not in r and r["all_matched"] == len(st) - 2
    odo, paper, _default = res.rows
    assert odo["all_trans_mean_m"] > 0 and paper["scans"] == len(st)
    data_json = json.loads((out / "benchmark.json").read_text())
    assert data_json["rows"][1]["config"] == "paper"
    assert read_tum(out / "sim.clf" / "odometry" / "trajectory.tum")[0].size == len(st)
    assert (out / "sim.clf" / "default" / "summary.json").is_file()
    with pytest.raises(ValueError, match="no log with a relations file"):
        run_benchmark(tmp_path / "bench", tmp_path / "b2")


def test_a_benchmark_stretch_with_no_relation_is_not_scored(sim_log, tmp_path):
    path, run = sim_log
    data = tmp_path / "data"
    data.mkdir()
    (data / "sim.clf").write_bytes(path.read_bytes())
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    write_relations(data / "sim.relations", st, truth, [(len(st) - 3, len(st) - 1)])
    res = run_benchmark(data, tmp_path / "o", max_scans=5, plot=False, loop_closure=False)
    assert all("not_scored" in r and "error" not in r for r in res.rows)
    assert res.rows[1]["scans"] == 5


def test_records_keep_their_type():
    assert LogRecord._fields == ("scan", "odometry", "truth")
    assert BENCHMARK_CONFIGS == ("odometry", "paper", "default")


# -- the deprecated paths: fuzzypos.logs and fuzzypos.evaluation re-export the new modules' names
def test_the_deprecated_paths_re_export_the_new_modules_objects():
    import fuzzypos.evaluation as old_evaluation
    import fuzzypos.logs as old_logs
    from fuzzypos.eval import metrics
    from fuzzypos.io import logs

    for old, new in ((old_logs, logs), (old_evaluation, metrics)):
        assert sorted(old.__all__) == sorted(new.__all__)
        for name in new.__all__:
            assert getattr(old, name) is getattr(new, name), name
