"""The command line: each command end to end on small simulated runs, and its errors."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.io import read_carmen, read_tum

runner = CliRunner()


def test_demo_writes_the_papers_figures_and_a_summary(tmp_path) -> None:
    out = tmp_path / "demo"
    res = runner.invoke(app, ["demo", "--out", str(out), "--laps", "0.15"])
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in out.iterdir())
    for number in range(13, 21):
        assert any(n.startswith(f"fig{number}_") and n.endswith(".png") for n in names), names
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scans"] > 20 and summary["distance_travelled_m"] > 0
    for name in ("odometry", "paper", "default"):
        e = summary[name]
        assert set(e) == {
            "final_position_error_m",
            "mean_position_error_m",
            "max_position_error_m",
            "mean_heading_error_deg",
            "scans_degraded",
        }
        assert e["max_position_error_m"] >= e["mean_position_error_m"] >= 0
    assert summary["odometry"]["scans_degraded"] == 0
    assert "default" in res.output and "odometry" in res.output


def test_simulate_writes_a_carmen_log_with_truth_and_a_tum_file(tmp_path) -> None:
    log, tum = tmp_path / "run.clf", tmp_path / "truth.tum"
    res = runner.invoke(
        app,
        [
            "simulate",
            "--out",
            str(log),
            "--tum",
            str(tum),
            "--world",
            "office",
            "--path",
            "circle",
            "--size",
            "1.0",
            "--laps",
            "0.1",
            "--seed",
            "3",
        ],
    )
    assert res.exit_code == 0, res.output
    records = list(read_carmen(log))
    stamps, poses = read_tum(tum)
    assert len(records) == len(stamps) > 5
    truth = np.array([r.truth.as_array() for r in records])
    np.testing.assert_allclose(truth, poses, atol=1e-9)
    odo = np.array([r.odometry.as_array() for r in records])
    assert np.abs(odo - truth).max() > 0  # the odometry is not the truth


def test_same_seed_gives_the_same_log_byte_for_byte(tmp_path) -> None:
    args = ["simulate", "--world", "gym", "--path", "square", "--size", "2.0", "--laps", "0.1"]
    logs = []
    for name, seed in (("a", "5"), ("b", "5"), ("c", "6")):
        log = tmp_path / f"{name}.clf"
        res = runner.invoke(app, [*args, "--out", str(log), "--seed", seed])
        assert res.exit_code == 0, res.output
        logs.append(log.read_bytes())
    assert logs[0] == logs[1]
    assert logs[0] != logs[2]


def test_simulate_follows_waypoints(tmp_path) -> None:
    log = tmp_path / "wp.clf"
    res = runner.invoke(
        app, ["simulate", "--out", str(log), "--world", "office", "--path", "-8,0;-5,0"]
    )
    assert res.exit_code == 0, res.output
    truth = np.array([r.truth.as_array() for r in read_carmen(log)])
    np.testing.assert_allclose(truth[0, :2], [-8.0, 0.0], atol=1e-9)
    assert abs(truth[-1, 0] - (-5.0)) < 0.2  # 3 m with a few percent of slip


def test_plot_scan_draws_figs_13_to_18(tmp_path) -> None:
    log = tmp_path / "run.clf"
    assert runner.invoke(app, ["simulate", "--out", str(log), "--laps", "0.05"]).exit_code == 0
    out = tmp_path / "figs"
    res = runner.invoke(app, ["plot-scan", str(log), "--index", "2", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert len(list(out.glob("fig1[3-8]_*.png"))) == 6


def test_errors_are_one_line_and_exit_2(tmp_path) -> None:
    cases = [
        ["simulate", "--out", str(tmp_path / "x.clf"), "--world", "moon"],
        ["simulate", "--out", str(tmp_path / "x.clf"), "--path", "zigzag"],
        ["simulate", "--out", str(tmp_path / "x.clf"), "--path", "1,2;3"],
        ["plot-scan", str(tmp_path / "missing.clf"), "--index", "0"],
        ["config", "--preset", "nope"],
        ["config", "--config", str(tmp_path / "missing.toml")],
    ]
    bad = tmp_path / "bad.clf"
    bad.write_text("FLASER 3 1.0 2.0\n")
    cases.append(["plot-scan", str(bad), "--index", "0"])
    for args in cases:
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (args, res.output)
        assert "Traceback" not in res.output
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("fuzzypos: error:"), (args, res.output)
