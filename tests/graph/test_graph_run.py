"""``fuzzypos run LOG --loop-closure`` (issue 13): the optimised trajectory, the front end's,
the g2o file, the occupancy map and the closures in summary.json; a clear error without
gtsam."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzzypos import Config
from fuzzypos.cli import app
from fuzzypos.eval import relations_errors
from fuzzypos.graph import LOOP_CLOSURE_FILES, GraphDependencyError, read_g2o
from fuzzypos.io import read_relations, read_tum
from fuzzypos.jobs import run_benchmark, run_log
from fuzzypos.jobs.benchmark import LOOP_CLOSURE_CONFIGS
from fuzzypos.jobs.folders import RESULT_FILES
from helpers import write_relations, write_sim_log

pytest.importorskip("gtsam")

runner = CliRunner()


@pytest.fixture(scope="module")
def loop_log(tmp_path_factory):
    """1.3 laps of a 1 m circle in the office (270 scans): the lap's end sees its start."""
    path = tmp_path_factory.mktemp("loop") / "loop.clf"
    return path, write_sim_log(path, laps=1.3, seed=0)


def test_run_with_loop_closure_writes_its_files(loop_log, tmp_path) -> None:
    path, run = loop_log
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--loop-closure", "--results", str(out)])
    assert res.exit_code == 0, res.output
    assert set(LOOP_CLOSURE_FILES) <= set(RESULT_FILES)
    for name in (*LOOP_CLOSURE_FILES, "trajectory.tum", "summary.json"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    lc = summary["loop_closure"]
    assert lc["closures"] and lc["closures_kept"] >= 1, lc
    for c in lc["closures"]:
        i, j = c["keyframes"]
        assert j - i >= Config().loop_closure.recent_keyframes and 0 <= c["weight"] <= 1
    stamps, optimised = read_tum(out / "trajectory.tum")[:2]
    _, frontend = read_tum(out / "trajectory_frontend.tum")[:2]
    assert len(stamps) == len(run.scans) == len(frontend)
    moved = np.hypot(*(optimised[:, :2] - frontend[:, :2]).T)
    assert 0.0 < moved.max() <= lc["max_correction_m"] + 1e-6
    # trajectory.clf carries the optimised poses, every scan refitted to the closed map
    flaser = [ln.split() for ln in (out / "trajectory.clf").read_text().splitlines()
              if ln.startswith("FLASER")]  # fmt: skip
    in_clf = np.array([[float(v) for v in t[2 + int(t[1]) : 5 + int(t[1])]] for t in flaser])
    np.testing.assert_allclose(in_clf, optimised, atol=1e-6)  # (the TUM file's precision)
    assert lc["realigned_scans"] > 0.9 * len(run.scans)
    truth = run.true_poses
    end = [float(np.hypot(*(p[-1, :2] - truth[-1, :2]))) for p in (frontend, optimised)]
    assert end[1] < end[0] + 0.01, end
    poses, edges = read_g2o(out / "graph.g2o")
    assert len(poses) == lc["keyframes"] and sum(e.closure for e in edges) == len(lc["closures"])
    yaml = (out / "map.yaml").read_text()
    assert "image: map.pgm" in yaml and "resolution: 0.05" in yaml
    header = (out / "map.pgm").read_bytes()[:2]
    assert header == b"P5"
    # the map's free cells are where the robot went (but where this circle, centred on the
    # corridor's north wall, passes through it: the simulator does not collide)
    data = (out / "map.pgm").read_bytes()
    w, h = (int(v) for v in data.split(b"\n")[2].split())
    img = np.frombuffer(data[-w * h :], dtype=np.uint8).reshape(h, w)
    origin = [float(v) for v in yaml.split("origin: [")[1].split("]")[0].split(",")[:2]]
    col = ((truth[:, 0] - origin[0]) / 0.05).astype(int)
    row = h - 1 - ((truth[:, 1] - origin[1]) / 0.05).astype(int)
    assert np.mean(img[row, col] == 254) > 0.8
    assert np.mean(img == 0) > 0.001  # walls


def test_loop_closure_is_off_by_default(loop_log, tmp_path) -> None:
    path, _ = loop_log
    summary = run_log(path, Config(), results_dir=tmp_path / "res", plot=False)
    assert "loop_closure" not in summary.summary
    assert not any((tmp_path / "res" / name).exists() for name in LOOP_CLOSURE_FILES)


def test_without_gtsam_the_error_says_how_to_install_it(loop_log, tmp_path, monkeypatch) -> None:
    path, _ = loop_log
    monkeypatch.setitem(sys.modules, "gtsam", None)  # import gtsam now raises ImportError
    cfg = Config().with_overrides({"loop_closure": {"enabled": True}})
    with pytest.raises(GraphDependencyError, match=r"pip install 'fuzzypos\[graph\]'"):
        run_log(path, cfg, results_dir=tmp_path / "res")
    assert not (tmp_path / "res").exists()  # refused before any output
    res = runner.invoke(app, ["run", str(path), "--loop-closure", "--results", str(tmp_path)])
    assert res.exit_code == 2 and "fuzzypos[graph]" in res.output


def test_run_scores_the_front_end_online_and_optimised_poses(loop_log, tmp_path) -> None:
    """With relations, summary.json has the optimised poses' figures and, beside them, the
    front end's and the online poses' (each scan's as first output); the CLI prints them."""
    path, run = loop_log
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    rel = tmp_path / "loop.relations"
    write_relations(rel, st, truth, [(0, k) for k in range(10, len(st), 10)])
    out = tmp_path / "res"
    args = ["run", str(path), "--loop-closure", "--relations", str(rel), "--results", str(out)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    lc = summary["loop_closure"]
    assert lc["mode"] == "online" and lc["map_scans"] > lc["keyframes"]
    for name in ("front end", "online", "optimised"):
        assert f"relations, {name}: all" in res.output, res.output
    figures = {
        "frontend": lc["relations_frontend"]["all_trans_mean_m"],
        "online": lc["relations_online"]["all_trans_mean_m"],
        "optimised": summary["relations"]["all_trans_mean_m"],
    }
    _, online = read_tum(out / "trajectory_online.tum")[:2]
    assert len(online) == len(run.scans)
    # each figure is its trajectory file's (on this short loop of a simulated office the
    # closure does not improve the relations from the start: docs/known-gaps.md)
    relations = read_relations(rel)
    for name, file in (("frontend", "trajectory_frontend.tum"), ("online", "trajectory_online.tum"),
                       ("optimised", "trajectory.tum")):  # fmt: skip
        stamps, poses = read_tum(out / file)[:2]
        scored = relations_errors(stamps, poses, relations).as_dict()["all_trans_mean_m"]
        assert scored == pytest.approx(figures[name], abs=1e-6), (name, figures)
    assert len(set(figures.values())) == 3, figures
    # until the first closure the online poses are the front end's
    _, frontend = read_tum(out / "trajectory_frontend.tum")[:2]
    first = min(c["stamps"][1] for c in lc["closures"])
    before = st < first
    np.testing.assert_allclose(online[before], frontend[before], atol=1e-6)


def test_the_benchmark_has_rows_for_loop_closure(loop_log, tmp_path) -> None:
    path, run = loop_log
    data = tmp_path / "data"
    data.mkdir()
    (data / "loop.clf").write_bytes(path.read_bytes())
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    write_relations(data / "loop.relations", st, truth, [(k, k + 5) for k in range(len(st) - 5)])
    res = run_benchmark(data, tmp_path / "bench", plot=False)
    configs = [r["config"] for r in res.rows]
    assert configs == ["odometry", "paper", "default", *LOOP_CLOSURE_CONFIGS]
    default, final, online = res.rows[2:]
    for r in (final, online):
        assert "error" not in r and r["all_matched"] == default["all_matched"] > 0
        assert r["loop_closure_seconds"] > 0 and r["scans"] == len(st)
    assert (tmp_path / "bench" / "loop.clf" / "loop_closure" / "trajectory_online.tum").is_file()
