"""The command line on inputs a new user gives it (issue 11): logs through pipes, corrupt
stamps, damaged gzip files, configs that are not UTF-8, odd bags. Bad input is one line
``fuzzypos: error: FILE[:LINE]: what is wrong`` and exit 2, never a traceback."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest

from fuzzypos.io.provenance import file_sha256
from helpers import fifo_with, invoke, make_bag, one_line_error, scan_ranges, write_sim_log


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("inputs") / "sim.clf"
    run = write_sim_log(path, laps=0.05)
    return path, run


def _stamped(path, stamps):
    """A CARMEN log of 3-beam scans (odometry moving 0.1 m a scan) at ``stamps``."""
    lines = [
        f"FLASER 3 1.0 2.0 3.0 0 0 0 {0.1 * k} 0 0 {t!r} host {t!r}" for k, t in enumerate(stamps)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


# -- pipes (item 2) ----------------------------------------------------------------------------
def test_info_through_a_pipe_sees_every_scan(sim_log, tmp_path):
    path, run = sim_log
    with fifo_with(tmp_path, gzip.compress(path.read_bytes())) as fifo:
        (line, *rest) = invoke(["info", str(fifo), "--json"], 0)
    data = json.loads("\n".join([line, *rest]))
    assert data["scans"] == len(run) and data["first_stamp"] == run.stamps[0]
    assert data["path"] == str(fifo)


def test_run_through_a_pipe_positions_every_scan(sim_log, tmp_path):
    path, run = sim_log
    out = tmp_path / "res"
    with fifo_with(tmp_path, path.read_bytes()) as fifo:
        invoke(["run", str(fifo), "--results", str(out)], 0)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scans"] == len(run)
    assert summary["input"]["sha256"] == file_sha256(path)  # what came through the pipe


# -- corrupt stamps (item 5) -------------------------------------------------------------------
def test_run_refuses_a_log_whose_stamps_are_corrupt(tmp_path):
    path = _stamped(tmp_path / "corrupt.clf", [5.0] * 60 + [5.0 + 2.0**32, 6.0])
    one_line_error(
        ["run", str(path), "--results", str(tmp_path / "r")],
        f"{path}: the scans' stamps are corrupt: 60 of 62 scans",
    )
    assert not (tmp_path / "r" / "trajectory.tum").exists()


def test_info_reports_corrupt_stamps_instead_of_a_duration(tmp_path):
    path = _stamped(tmp_path / "corrupt.clf", [5.0] * 60 + [5.0 + 2.0**32, 6.0])
    lines = invoke(["info", str(path)], 0)
    warning = [ln for ln in lines if ln.startswith("fuzzypos: warning: ")]
    assert len(warning) == 1 and f"{path}: the scans' stamps are corrupt" in warning[0]
    assert any("unknown: the stamps are corrupt" in ln for ln in lines)
    assert not any("4294967" in ln for ln in lines if "duration" in ln)


def test_run_warns_of_a_few_repeated_stamps_and_runs(tmp_path):
    stamps = [0.1 * k for k in range(30)]
    stamps[10] = stamps[9]
    path = _stamped(tmp_path / "few.clf", stamps)
    lines = invoke(["run", str(path), "--results", str(tmp_path / "r")], 0)
    assert any(
        ln.startswith("fuzzypos: warning: ") and "1 of 30 scans repeat the stamp" in ln
        for ln in lines
    )
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["scans"] == 30


# -- damaged files (items 8 and 9) -------------------------------------------------------------
def test_evaluate_with_a_damaged_gzip_trajectory_is_one_line(tmp_path):
    text = "".join(f"{k}.0 {k} 0 0 0 0 0 1\n" for k in range(200))
    tum = tmp_path / "est.tum.gz"
    tum.write_bytes(gzip.compress(text.encode())[:-20])  # cut short
    rel = tmp_path / "log.relations"
    rel.write_text("0.0 1.0 1 0 0 0 0 0\n")
    one_line_error(["evaluate", str(tum), "--relations", str(rel)], f"{tum}:", "gzip stream")
    one_line_error(["evaluate", str(rel), "--reference", str(tum)], f"{rel}:")  # not a TUM file


def test_a_config_that_is_not_utf8_is_one_line(sim_log, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(b"[odometry]\n# \xe9t\xe9\n")
    one_line_error(["info", str(sim_log[0]), "--config", str(cfg)], f"{cfg}:2: not UTF-8")
    cfg.write_text("[odometry]\nmax_speed = 1" + "0" * 400 + "\n")
    one_line_error(["info", str(sim_log[0]), "--config", str(cfg)], "max_speed is too large")


# -- odd bags (items 6 and 9) ------------------------------------------------------------------
def test_info_on_a_bag_whose_angles_disagree_is_one_line(tmp_path):
    def build(b):
        return [
            ("/scan", 1.0, b.scan(1.0, scan_ranges(0))),
            ("/scan", 2.0, b.scan(2.0, scan_ranges(1), angle_min=1.0, angle_max=-1.0)),
        ]

    bag = make_bag(tmp_path, "ros1", build)
    one_line_error(["info", str(bag)], f"{bag}:2: /scan: angle_max -1 lies below angle_min 1")


def test_info_on_a_bag_whose_scans_have_no_ranges(tmp_path):
    def build(b):
        empty = np.zeros(0, dtype=np.float32)
        return [("/scan", 1.0, b.scan(1.0, empty)), ("/scan", 2.0, b.scan(2.0, empty))]

    lines = invoke(["info", str(make_bag(tmp_path, "ros1", build))], 0)
    assert any("2 scans have no ranges" in ln for ln in lines)
