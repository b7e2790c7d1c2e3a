"""The run job and its results folder (fuzzypos.run), scoring trajectory files
(fuzzypos.scoring), provenance (fuzzypos.provenance), the benchmark (fuzzypos.benchmark), and
the fuzzypos.results compatibility names."""

from __future__ import annotations

import hashlib
import json
import math
import subprocess

import numpy as np
import pytest

from fuzzypos.benchmark import BENCHMARK_CONFIGS, find_benchmark_logs, run_benchmark
from fuzzypos.config import Config
from fuzzypos.geometry import Pose2D
from fuzzypos.io import CarmenReader, LogRecord, read_tum
from fuzzypos.logs import open_log
from fuzzypos.provenance import file_sha256, git_hash
from fuzzypos.run import log_name, run_log, write_estimate_clf
from fuzzypos.scan import LaserScan
from fuzzypos.scoring import evaluate_trajectory
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
    with pytest.raises(ValueError, match="no scans in the chosen stretch"):
        run_log(path, Config(), results_dir=tmp_path / "b", start=1e6)
    assert not (tmp_path / "b" / "trajectory.clf").exists()


def test_run_log_on_an_empty_log_is_an_error(tmp_path):
    p = tmp_path / "empty.clf"
    p.write_text("# nothing\n")
    with pytest.raises(ValueError, match="no scans"):
        run_log(p, results_dir=tmp_path / "r")


def test_a_failure_mid_log_leaves_no_partial_trajectory(sim_log, tmp_path):
    path, _run = sim_log
    lines = path.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("FLASER")) + 10
    bad = tmp_path / "bad.clf"
    bad.write_text("".join([*lines[:k], "FLASER 3 1 2\n", *lines[k:]]))
    out = tmp_path / "res"
    with pytest.raises(ValueError, match="FLASER"):
        run_log(bad, results_dir=out)
    assert list(out.iterdir()) == []
    res = run_log(open_log(bad, skip_bad_lines=True), results_dir=out, plot=False)
    assert res.summary["bad_lines_skipped"] == 1


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


# -- the estimate as CARMEN ------------------------------------------------------------------
def test_write_estimate_clf_keeps_a_span_geometry_and_an_odd_mount(tmp_path):
    n = 180
    inc = math.pi / (n - 1)  # exactly -90° … +90°, like the aces bag
    mount = Pose2D(0.2, 0.05, 0.1)
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
    assert "convention 'span'" in text and "--laser-offset" in text
    back = list(CarmenReader(p, convention="span", laser_offset=mount).records())
    assert [b.scan.stamp for b in back] == [1.0, 1.001, 1.002, 1.003]
    np.testing.assert_allclose(back[0].scan.angles, recs[0][0].angles, atol=1e-12)
    assert back[1].odometry == Pose2D(0, 1, 0)
    assert back[2].odometry == Pose2D(2, 0, 0)  # no odometry: the estimate
    assert not back[0].scan.valid[3] and back[0].scan.valid[0]


def test_write_estimate_clf_leaves_nothing_for_an_unrepresentable_geometry(tmp_path):
    scan = LaserScan(np.ones(5), 0.0, 0.1)  # not symmetric about the x axis
    p = tmp_path / "x.clf"
    assert write_estimate_clf(p, [(scan, Pose2D(), None, None)]) == 0
    assert not p.exists() and not list(tmp_path.iterdir())


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
    res = run_benchmark(tmp_path / "data", out, plot=False)
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
    res = run_benchmark(data, tmp_path / "o", max_scans=5, plot=False)
    assert all("not_scored" in r and "error" not in r for r in res.rows)
    assert res.rows[1]["scans"] == 5


def test_records_keep_their_type():
    assert LogRecord._fields == ("scan", "odometry", "truth")
    assert BENCHMARK_CONFIGS == ("odometry", "paper", "default")


# -- fuzzypos.results: the names it had before the split (the README names them) ----------------
def test_the_results_compatibility_names_are_the_new_modules_objects():
    import fuzzypos.results as results_mod
    from fuzzypos import benchmark, provenance, scoring
    from fuzzypos import run as run_mod

    home = {
        "BENCHMARK_CONFIGS": benchmark,
        "BenchmarkResult": benchmark,
        "find_benchmark_logs": benchmark,
        "run_benchmark": benchmark,
        "Evaluation": scoring,
        "evaluate_trajectory": scoring,
        "file_sha256": provenance,
        "git_hash": provenance,
        "RunSummary": run_mod,
        "default_results_dir": run_mod,
        "log_name": run_mod,
        "run_log": run_mod,
        "write_estimate_clf": run_mod,
    }
    assert sorted(results_mod.__all__) == sorted(home)
    for name, module in home.items():
        assert getattr(results_mod, name) is getattr(module, name), name
