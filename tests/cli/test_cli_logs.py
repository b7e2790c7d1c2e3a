"""The commands for real logs (info, run, evaluate, benchmark): end to end on small simulated
logs and bags, their errors, and a stretch of each shared log (skipped where absent)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.config import Config
from fuzzypos.io import read_tum, write_tum
from helpers import DATA, SCAN_T, make_bag, standard, write_relations, write_sim_log

runner = CliRunner()

INTEL = DATA / "intel" / "intel.clf.gz"
ACES = DATA / "aces" / "aces.clf.gz"
ACES_BAG = DATA / "aces" / "aces.bag"
needs_data = pytest.mark.skipif(
    not (INTEL.is_file() and ACES.is_file() and ACES_BAG.is_file()),
    reason=f"the shared logs are not in {DATA} (see its README.md; CI has them)",
)


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    path = d / "sim.clf"
    run = write_sim_log(path)
    return path, run


def ok(args: list[str]):
    res = runner.invoke(app, args)
    assert res.exit_code == 0, (args, res.output)
    assert "Traceback" not in res.output
    return res


def one_line_error(args: list[str], expect: str = "") -> str:
    res = runner.invoke(app, args)
    assert res.exit_code == 2, (args, res.output)
    assert "Traceback" not in res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("fuzzypos: error:"), (args, res.output)
    assert expect in lines[0], (expect, lines[0])
    return lines[0]


# -- info --------------------------------------------------------------------------------------
def test_info_on_a_simulated_log(sim_log):
    path, run = sim_log
    res = ok(["info", str(path)])
    for text in ("carmen", str(len(run)), "180", "yes"):
        assert text in res.output
    data = json.loads(ok(["info", str(path), "--json"]).output)
    assert data["kind"] == "carmen" and data["scans"] == len(run)
    assert data["has_odometry"] and data["has_truth"] and data["bad_lines"] == 0
    assert data["first_stamp"] == run.stamps[0] and data["last_stamp"] == run.stamps[-1]


def test_info_on_a_bag_named_clf(tmp_path):
    bag = make_bag(tmp_path, "ros1", standard).rename(tmp_path / "bag.clf")
    data = json.loads(ok(["info", str(bag), "--json"]).output)
    assert data["kind"] == "ros1" and data["scans"] == len(SCAN_T) and data["beams"] == [9]


# -- run ---------------------------------------------------------------------------------------
def test_run_writes_the_results_folder(sim_log, tmp_path):
    path, run = sim_log
    out = tmp_path / "res"
    tum = tmp_path / "est.tum"
    res = ok(["run", str(path), "--results", str(out), "-o", str(tum), "--preset", "paper"])
    assert "scans/s" in res.output and f"results in {out}/" in res.output
    assert "against the log's truth" in res.output
    for name in ("trajectory.tum", "trajectory.clf", "config.toml", "path.png", "summary.json"):
        assert (out / name).is_file(), name
    stamps, _poses = read_tum(tum)
    assert stamps.tolist() == list(run.stamps)
    assert Config.from_toml(out / "config.toml") == Config.preset("paper")
    s = json.loads((out / "summary.json").read_text())
    assert s["config"]["preset"] == "paper" and s["scans"] == len(run)


def test_run_default_folder_stretch_and_config_file(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.toml"
    cfg.write_text("[matching]\nmutual = false\n")
    ok(
        [
            "run",
            str(path),
            "--config",
            str(cfg),
            "--start",
            "0.5",
            "--end",
            "1.5",
            "--max-scans",
            "4",
            "--laser-offset",
            "0.1,0,0",
        ]
    )
    out = tmp_path / "results" / "sim.clf" / "latest"
    stamps, _ = read_tum(out / "trajectory.tum")
    assert len(stamps) == 4 and stamps[0] == pytest.approx(0.5)
    s = json.loads((out / "summary.json").read_text())
    assert s["config"]["file"] == str(cfg)
    assert s["input"]["options"]["laser_offset"] == [0.1, 0.0, 0.0]
    assert Config.from_toml(out / "config.toml").matching.mutual is False


def test_run_on_a_ros2_bag(tmp_path):
    bag = make_bag(tmp_path, "ros2-sqlite3", standard)
    out = tmp_path / "res"
    ok(["run", str(bag), "--results", str(out)])
    stamps, _ = read_tum(out / "trajectory.tum")
    assert stamps.tolist() == pytest.approx(SCAN_T, abs=1e-9)
    assert json.loads((out / "summary.json").read_text())["input"]["kind"] == "ros2"


def test_run_skip_bad_lines(sim_log, tmp_path):
    path, _run = sim_log
    lines = path.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("FLASER")) + 3
    bad = tmp_path / "bad.clf"
    bad.write_text("".join([*lines[:k], "FLASER 3 1 2\n", *lines[k:]]))
    one_line_error(["run", str(bad), "--results", str(tmp_path / "r")], "bad.clf:")
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["partial"] is True
    res = ok(["run", str(bad), "--results", str(tmp_path / "r"), "--skip-bad-lines", "--overwrite"])
    assert "1 bad lines skipped" in res.output


# -- errors ------------------------------------------------------------------------------------
def test_errors_are_one_line_and_exit_2(sim_log, tmp_path):
    path, _ = sim_log
    garbage = tmp_path / "garbage.clf"
    garbage.write_bytes(b"\x00\x01\x02\x03" * 100)
    empty = tmp_path / "empty.clf"
    empty.write_text("# no scans\n")
    r = str(tmp_path / "r")
    one_line_error(["run", str(tmp_path / "missing.clf")], "missing.clf: No such file")
    one_line_error(["info", str(tmp_path / "missing.bag")], "missing.bag")
    one_line_error(["run", str(garbage), "--results", r], "garbage.clf: not a log")
    one_line_error(["info", str(garbage)], "not a log")
    one_line_error(["run", str(tmp_path)], "without metadata.yaml")
    one_line_error(["run", str(empty), "--results", r], "no scans")
    for offset in ("1,2", "a,b,c", "1,2,inf"):
        one_line_error(
            ["run", str(path), "--laser-offset", offset, "--results", r], "--laser-offset"
        )
    one_line_error(["run", str(path), "--preset", "nope", "--results", r], "unknown preset")
    one_line_error(["run", str(path), "--config", str(tmp_path / "no.toml")], "no.toml")
    one_line_error(["run", str(path), "--odometry", "magic", "--results", r], "odometry")
    one_line_error(["run", str(path), "--fov", "0", "--results", r], "--fov")
    one_line_error(["run", str(path), "--start", "2", "--end", "1", "--results", r], "end")
    one_line_error(["run", str(path), "--start", "-1", "--results", r], "start")
    one_line_error(["run", str(path), "--max-scans", "0", "--results", r], "--max-scans")
    one_line_error(["run", str(path), "--start", "1000", "--results", r], "no scans")
    one_line_error(["evaluate", str(tmp_path / "x.tum")], "--relations")
    one_line_error(["evaluate", str(tmp_path / "x.tum"), "--reference", str(path)], "x.tum")
    one_line_error(["evaluate", str(path), "--reference", str(path)], "sim.clf:")
    one_line_error(["benchmark", "--data", str(tmp_path / "nothing")], "nothing")
    one_line_error(["benchmark", "--data", str(tmp_path), "--out", r], "no log with a relations")
    one_line_error(["benchmark", "--max-scans", "0"], "--max-scans")


def test_a_bag_with_two_scan_topics_needs_a_choice(tmp_path):
    bag = make_bag(tmp_path, "ros1", lambda b: standard(b, scan_topics=("/a", "/b")))
    one_line_error(["run", str(bag), "--results", str(tmp_path / "r")], "--scan-topic")
    ok(["run", str(bag), "--scan-topic", "/b", "--results", str(tmp_path / "r")])


# -- evaluate ------------------------------------------------------------------------------------
def test_evaluate_an_estimate_equal_to_the_reference_scores_zero(sim_log, tmp_path):
    _path, run = sim_log
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    est = tmp_path / "truth.tum"
    write_tum(est, st, truth)
    rel = tmp_path / "sim.relations"
    write_relations(rel, st, truth, [(k, k + 1) for k in range(len(st) - 1)])
    res = ok(["evaluate", str(est), "--relations", str(rel), "--reference", str(est)])
    assert "0.000 ± 0.000 m / 0.00 ± 0.00°" in res.output
    assert "ATE" in res.output and "RMSE 0.0000 m" in res.output
    data = json.loads(ok(["evaluate", str(est), "--relations", str(rel), "--json"]).output)
    assert data["relations"]["all_matched"] == len(st) - 1
    assert data["relations"]["all_trans_max_m"] < 1e-9 and data["ate"] is None


# -- benchmark -----------------------------------------------------------------------------------
def test_benchmark_on_a_temporary_data_dir(sim_log, tmp_path):
    path, run = sim_log
    data = tmp_path / "data" / "sim"
    data.mkdir(parents=True)
    (data / "sim.clf").write_bytes(path.read_bytes())
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    write_relations(data / "sim.relations", st, truth, [(k, k + 2) for k in range(len(st) - 2)])
    out = tmp_path / "bench"
    res = ok(
        ["benchmark", "--data", str(tmp_path / "data"), "--out", str(out), "--no-loop-closure"]
    )
    for text in ("sim.clf", "odometry", "paper", "default", "±"):
        assert text in res.output
    rows = json.loads((out / "benchmark.json").read_text())["rows"]
    assert [r["config"] for r in rows] == ["odometry", "paper", "default"]
    assert all(r["all_matched"] == len(st) - 2 for r in rows)
    env_rows = json.loads(
        runner.invoke(
            app,
            ["benchmark", "--out", str(tmp_path / "b2"), "--json", "--no-loop-closure"],
            env={"FUZZYPOS_DATA": str(tmp_path / "data")},
        ).output
    )
    assert len(env_rows) == 3


def test_benchmark_exits_1_when_a_run_fails(sim_log, tmp_path):
    """A broken log among good ones: its rows fail (named, with the error), the good log's
    rows are scored, and the exit code is 1 (a failed run, not bad input), also with --json."""
    path, run = sim_log
    data = tmp_path / "data"
    (data / "sim").mkdir(parents=True)
    (data / "broken").mkdir()
    (data / "sim" / "sim.clf").write_bytes(path.read_bytes())
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    pairs = [(k, k + 2) for k in range(len(st) - 2)]
    write_relations(data / "sim" / "sim.relations", st, truth, pairs)
    lines = path.read_text().splitlines()
    lines[len(lines) // 2] = "FLASER 3 1.0 x 2.0"
    (data / "broken" / "broken.clf").write_text("\n".join(lines) + "\n")
    write_relations(data / "broken" / "broken.relations", st, truth, pairs)
    res = runner.invoke(app, ["benchmark", "--data", str(data), "--out", str(tmp_path / "b")])
    assert res.exit_code == 1, res.output
    assert "broken.clf" in res.output and "failed" in res.output
    rows = json.loads((tmp_path / "b" / "benchmark.json").read_text())["rows"]
    assert any("error" in r and r["log"] == "broken.clf" for r in rows)
    assert any("error" not in r and r["log"] == "sim.clf" for r in rows)
    res = runner.invoke(
        app, ["benchmark", "--data", str(data), "--out", str(tmp_path / "j"), "--json"]
    )
    assert res.exit_code == 1
    assert any("error" in r for r in json.loads(res.output))


# -- the shared logs -------------------------------------------------------------------------------
@needs_data
def test_run_and_evaluate_a_stretch_of_intel(tmp_path):
    out = tmp_path / "intel"
    res = ok(["run", str(INTEL), "--max-scans", "300", "--results", str(out)])
    assert "300 scans" in res.output
    stamps, _ = read_tum(out / "trajectory.tum")
    assert len(stamps) == 300
    data = json.loads(
        ok(
            [
                "evaluate",
                str(out / "trajectory.tum"),
                "--relations",
                str(INTEL.with_name("intel.relations")),
                "--reference",
                str(INTEL.with_name("intel.keyframes.tum")),
                "--json",
            ]
        ).output
    )
    assert data["relations"]["all_matched"] > 0 and data["ate"]["matched"] > 0


@needs_data
def test_info_on_the_aces_bag_and_log_agree():
    bag = json.loads(ok(["info", str(ACES_BAG), "--json"]).output)
    log = json.loads(ok(["info", str(ACES), "--json"]).output)
    assert bag["kind"] == "ros1" and log["kind"] == "carmen"
    assert bag["scans"] == log["scans"] == 7374
    assert bag["first_stamp"] == pytest.approx(log["first_stamp"], abs=1e-6)


@needs_data
def test_benchmark_a_stretch_of_each_shared_log(tmp_path):
    out = tmp_path / "bench"
    args = ["benchmark", "--data", str(DATA), "--out", str(out), "--max-scans", "300"]
    rows = json.loads(ok([*args, "--json", "--no-loop-closure"]).output)
    logs = {r["log"] for r in rows}
    # the shared folder has grown from intel and aces to four logs (fr079 as a CARMEN log and a
    # bag, fr-clinic): the first three are there, every log found is one of them, three rows each
    known = {"intel.clf.gz", "aces.clf.gz", "aces.bag", "fr079.clf.gz", "fr079.bag"}
    assert {"intel.clf.gz", "aces.clf.gz", "aces.bag"} <= logs <= known | {"fr-clinic.clf.gz"}
    assert len(rows) == 3 * len(logs)
    for r in rows:
        assert "error" not in r, r
        assert r["all_matched"] > 0 and r["scans"] == 300
    odo = next(r for r in rows if r["log"] == "aces.clf.gz" and r["config"] == "odometry")
    assert 0 < odo["all_trans_mean_m"] < 1.0


def test_plot_scan_on_a_ros1_bag(tmp_path):
    bag = make_bag(tmp_path, "ros1", standard)
    out = tmp_path / "figs"
    ok(["plot-scan", str(bag), "--index", "2", "--out", str(out)])
    assert len(list(out.glob("*.png"))) == 6
