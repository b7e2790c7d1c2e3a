"""``fuzzypos localize LOG --map MAP.yaml`` (issue 37) with the localizer contract's test double
(``localizer_double``) in place of ``fuzzypos.localization``: exit 0 and when it localised,
exit 1 and one line where it never did, exit 2 and one line for a bad map, an initial pose off
the map or a bad option, exit 130 on Ctrl-C with the scans done kept."""

from __future__ import annotations

import json

import pytest

import localizer_double as double
from fuzzypos import sim
from fuzzypos.io import open_log
from fuzzypos.jobs import localize as job
from fuzzypos.pipeline import warm
from helpers import invoke, one_line_error, write_sim_log, write_world_map


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli_localize")
    log = folder / "sim.clf"
    write_sim_log(log, laps=0.2, seed=4)
    yaml_path, _, _ = write_world_map(folder / "map", sim.world_by_name("office"), 0.05)
    truth = {r.scan.stamp: (r.truth.x, r.truth.y, r.truth.theta) for r in open_log(log).records()}
    return log, yaml_path, truth


@pytest.fixture(autouse=True)
def _double(world, monkeypatch):
    """The command's localizer is the double (and no kernels are compiled for it)."""
    monkeypatch.setattr(job, "_LOCALIZER", ("localizer_double", "Localizer"))
    monkeypatch.setattr(warm, "compile_kernels", lambda cfg, compiling=None, *, in_map=False: 0.0)
    monkeypatch.setattr(double, "TRUTH", world[2])
    monkeypatch.setattr(double, "SETTINGS", {"searching": 5})


def test_a_localised_log_exits_0_saying_when(world, tmp_path) -> None:
    log, yaml_path, truth = world
    out = tmp_path / "r"
    lines = invoke(["localize", str(log), "--map", str(yaml_path), "--results", str(out)], 0)
    assert lines[0].startswith("localised at scan 6 (0.5 s into the log, after ")
    assert f"tracking {len(truth) - 5} of {len(truth)} scans, lost 0 times" in lines[0]
    assert lines[-1] == f"results in {out}/"
    data = json.loads((out / "summary.json").read_text())
    assert data["localised"] is True and data["scans_with_pose"] == len(truth) - 5


def test_a_log_that_never_localises_exits_1_with_one_line(world, tmp_path, monkeypatch) -> None:
    log, yaml_path, truth = world
    monkeypatch.setattr(double, "SETTINGS", {"searching": None})
    out = tmp_path / "r"
    lines = invoke(["localize", str(log), "--map", str(yaml_path), "--results", str(out)], 1)
    assert lines == [
        (
            f"fuzzypos: {log} never localised in {yaml_path} over {len(truth)} scans "
            f'({len(truth)} searching); results in {out}/ (summary.json: "localised": false)'
        )
    ]
    assert json.loads((out / "summary.json").read_text())["localised"] is False
    assert not [ln for ln in (out / "trajectory.tum").read_text().splitlines() if ln[:1] != "#"]


def test_an_initial_pose_off_the_map_exits_2_with_one_line(world, tmp_path) -> None:
    log, yaml_path, _ = world
    out = tmp_path / "r"
    args = ["localize", str(log), "--map", str(yaml_path), "--results", str(out)]
    one_line_error(
        [*args, "--initial-pose", "30,0,45"], "--initial-pose (30 m, 0 m, 45°) lies outside the map"
    )
    one_line_error([*args, "--initial-pose", "1,2"], "--initial-pose '1,2': expected three")
    one_line_error([*args, "--initial-pose", "1,0,0", "--initial-sigma", "0,5"], "--initial-sigma")
    one_line_error([*args, "--initial-sigma", "0.5,5"], "--initial-sigma needs --initial-pose")
    assert not out.exists()
    invoke([*args, "--initial-pose", "1,0,90", "--initial-sigma", "0.3,10"], 0)
    data = json.loads((out / "summary.json").read_text())
    assert data["initial_pose"] == pytest.approx({"x": 1.0, "y": 0.0, "theta_deg": 90.0})


def test_a_bad_map_exits_2_with_one_line_naming_it(world, tmp_path) -> None:
    log = world[0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: map.pgm\nresolution: 0.05\norigin: [0, 0]\n")
    one_line_error(["localize", str(log), "--map", str(bad)], f"{bad}:3: 'origin'")
    one_line_error(["localize", str(log), "--map", str(tmp_path / "no.yaml")], "No such file")


def test_ctrl_c_exits_130_keeping_the_scans_done(world, tmp_path, monkeypatch) -> None:
    log, yaml_path, _ = world
    monkeypatch.setattr(double, "SETTINGS", {"searching": 2, "fail_at": {8: KeyboardInterrupt()}})
    out = tmp_path / "r"
    lines = invoke(["localize", str(log), "--map", str(yaml_path), "--results", str(out)], 130)
    assert lines == [
        (
            f"fuzzypos: interrupted at scan 9; the 8 scans before it are kept in {out}/ "
            '(summary.json: "partial": true)'
        )
    ]
    assert json.loads((out / "summary.json").read_text())["partial_reason"] == (
        "interrupted at scan 9"
    )


def test_the_bag_frames_need_a_bag(world) -> None:
    log, yaml_path, _ = world
    one_line_error(
        ["localize", str(log), "--map", str(yaml_path), "--map-frame", "world"], "give --bag-out"
    )


def test_without_a_localizer_installed_exit_2_with_one_line(world, monkeypatch) -> None:
    log, yaml_path, _ = world
    monkeypatch.setattr(job, "_LOCALIZER", ("fuzzypos.no_such_localizer", "Localizer"))
    one_line_error(
        ["localize", str(log), "--map", str(yaml_path)],
        "fuzzypos.no_such_localizer is not installed: no localizer",
    )


def test_a_log_that_lost_itself_says_how_often(world, tmp_path, monkeypatch) -> None:
    log, yaml_path, truth = world
    monkeypatch.setattr(double, "SETTINGS", {"searching": 2, "lost": range(6, 9)})
    lines = invoke(["localize", str(log), "--map", str(yaml_path), "--results", str(tmp_path)], 0)
    assert f"tracking {len(truth) - 5} of {len(truth)} scans, lost 1 time, " in lines[0]
