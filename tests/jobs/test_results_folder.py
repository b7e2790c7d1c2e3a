"""A results folder holds one run (issue 11): a new dated folder by default with a ``latest``
link, folders of other runs refused or (``--overwrite``) cleared, output paths checked before
the run, partial results kept and marked after an error or Ctrl-C, and ``trajectory.clf`` for
logs whose scans FLASER cannot describe (ROBOTLASER1)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.io import CarmenReader, read_carmen, read_tum
from fuzzypos.jobs import ResultsFolderError, default_results_dir, run_log, write_estimate_clf
from fuzzypos.jobs.folders import log_name
from fuzzypos.pipeline import Positioner
from helpers import write_sim_log

runner = CliRunner()
_UPDATE = Positioner.update


def interrupt_at(monkeypatch: pytest.MonkeyPatch, n: int) -> None:
    """Ctrl-C inside the run: ``Positioner.update`` raises KeyboardInterrupt at its n-th call."""
    calls: list[float] = []

    def update(self, scan, odometry):
        calls.append(scan.stamp)
        if len(calls) == n:
            raise KeyboardInterrupt
        return _UPDATE(self, scan, odometry)

    monkeypatch.setattr(Positioner, "update", update)


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("folders") / "sim.clf"
    return path, write_sim_log(path)


def lines_of(res) -> list[str]:
    return [ln for ln in res.output.splitlines() if ln.strip()]


def one_line_error(args: list[str], expect: str) -> str:
    res = runner.invoke(app, args)
    assert res.exit_code == 2 and "Traceback" not in res.output, (args, res.output)
    (line,) = lines_of(res)
    assert line.startswith("fuzzypos: error: ") and expect in line, line
    return line


# -- names -----------------------------------------------------------------------------------------
def test_log_name_keeping_the_format_drops_only_a_compression_suffix():
    assert log_name("data/aces.clf.gz", keep_format=True) == "aces.clf"
    assert log_name("aces.bag", keep_format=True) == "aces.bag"
    assert log_name("INTEL.CLF.GZ", keep_format=True) == "INTEL.CLF"
    assert log_name("my_bag/", keep_format=True) == "my_bag"
    assert log_name(".gz", keep_format=True) == ".gz"


def test_a_log_and_a_bag_of_the_same_name_get_their_own_folders():
    clf, bag = default_results_dir("d/X.clf.gz", when=0.0), default_results_dir("X.bag", when=0.0)
    assert clf.parent.as_posix() == "results/X.clf" and bag.parent.as_posix() == "results/X.bag"
    assert clf.name == bag.name and len(clf.name) == len("1970-01-01_00-00-00")


def test_every_default_run_gets_a_new_folder_and_latest_links_to_it(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    monkeypatch.chdir(tmp_path)
    first = run_log(path, max_scans=3, plot=False).results_dir
    second = run_log(path, max_scans=3, plot=False).results_dir  # within a second: "-2"
    assert first != second and first.parent == second.parent == Path("results", "sim.clf")
    latest = first.parent / "latest"
    assert latest.is_symlink() and os.readlink(latest) == second.name
    assert (latest / "summary.json").is_file() and not list(first.parent.glob(".*"))
    assert sorted(p.name for p in first.parent.iterdir()) == sorted(
        [first.name, second.name, "latest"]
    )


# -- one run per folder ----------------------------------------------------------------------------
def test_a_folder_of_another_run_is_refused_and_overwrite_clears_it(sim_log, tmp_path):
    path, _run = sim_log
    out = tmp_path / "res"
    run_log(path, results_dir=out, max_scans=30)  # with path.png
    assert (out / "path.png").is_file()
    with pytest.raises(ResultsFolderError, match=r"res: holds the results of another run \("):
        run_log(path, results_dir=out, max_scans=3, plot=False)
    res = run_log(path, results_dir=out, max_scans=3, plot=False, overwrite=True)
    assert res.scans == 3 and not (out / "path.png").exists()  # nothing of the old run left
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["trajectory.tum", "trajectory.clf", "config.toml", "covariance.csv", "summary.json"]
    )


def test_overwrite_clears_what_the_run_wrote_into_the_folder(sim_log, tmp_path):
    path, _run = sim_log
    out = tmp_path / "res"
    run_log(path, results_dir=out, out_tum=out / "mine.tum", max_scans=3, plot=False)
    assert (out / "mine.tum").is_file()
    run_log(path, results_dir=out, max_scans=2, plot=False, overwrite=True)
    assert not (out / "mine.tum").exists()  # listed in the old summary.json's files


def test_overwrite_never_deletes_what_fuzzypos_did_not_write(sim_log, tmp_path):
    path, _run = sim_log
    out = tmp_path / "res"
    run_log(path, results_dir=out, max_scans=3, plot=False)
    (out / "notes.txt").write_text("mine\n")
    before = sorted(p.name for p in out.iterdir())
    with pytest.raises(ResultsFolderError, match=r"did not write \(notes\.txt\): not clearing"):
        run_log(path, results_dir=out, max_scans=3, plot=False, overwrite=True)
    assert sorted(p.name for p in out.iterdir()) == before
    # a trajectory.tum without fuzzypos's summary.json or config.toml is not ours to delete
    other = tmp_path / "other"
    other.mkdir()
    (other / "trajectory.tum").write_text("1 0 0 0 0 0 0 1\n")
    with pytest.raises(ResultsFolderError, match=r"no fuzzypos summary\.json or config\.toml"):
        run_log(path, results_dir=other, overwrite=True)
    assert (other / "trajectory.tum").read_text() == "1 0 0 0 0 0 0 1\n"
    # a folder of other things is no results folder at all
    (tmp_path / "stuff").mkdir()
    (tmp_path / "stuff" / "a.txt").write_text("")
    with pytest.raises(ResultsFolderError, match=r"is not empty \(a\.txt\) and not a results"):
        run_log(path, results_dir=tmp_path / "stuff", overwrite=True)
    (tmp_path / "file").write_text("")
    with pytest.raises(NotADirectoryError):
        run_log(path, results_dir=tmp_path / "file")


def test_output_paths_are_checked_before_the_run(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log

    def never(self, scan, odometry):
        raise AssertionError("the run started")

    monkeypatch.setattr(Positioner, "update", never)
    out = tmp_path / "res"
    with pytest.raises(FileNotFoundError, match="no folder") as info:
        run_log(path, results_dir=out, out_tum=tmp_path / "nonexistent" / "x.tum")
    assert info.value.filename == str(tmp_path / "nonexistent" / "x.tum")
    with pytest.raises(IsADirectoryError):
        run_log(path, results_dir=out, out_tum=tmp_path)
    (tmp_path / "b.bag").write_bytes(b"")
    with pytest.raises(FileExistsError, match="never overwritten"):
        run_log(path, results_dir=out, bag_out=tmp_path / "b.bag")
    assert not out.exists()


# -- ROBOTLASER1 logs ------------------------------------------------------------------------------
def test_trajectory_clf_of_a_robotlaser1_log(sim_log, tmp_path):
    """A log whose scans FLASER cannot describe (0.007° off, a sideways mount) gets its
    trajectory.clf as ROBOTLASER1: the same beams, the estimate as the robot pose, and the log's
    odometry (ODOM lines)."""
    path, run = sim_log
    log = tmp_path / "rl.clf"
    records = []
    for rec in read_carmen(path):
        scan = dataclasses.replace(
            rec.scan,
            angle_min=rec.scan.angle_min + math.radians(0.007),
            sensor_pose=dataclasses.replace(rec.scan.sensor_pose, y=0.01),
        )
        records.append((scan, rec.odometry, rec.odometry, rec.truth))
    assert write_estimate_clf(log, records) == len(run)
    res = run_log(log, results_dir=tmp_path / "res", plot=False)
    assert "trajectory.clf" in res.files and res.scans == len(run)
    text = (tmp_path / "res" / "trajectory.clf").read_text()
    assert "\nFLASER " not in text and text.count("\nROBOTLASER1 ") == len(run)
    back = list(CarmenReader(res.files["trajectory.clf"]).records())
    np.testing.assert_allclose([b.odometry.as_array() for b in back], res.poses, atol=1e-12)
    odom = list(CarmenReader(res.files["trajectory.clf"], odometry="interpolated").records())
    for b, o, (scan, _est, odometry, truth) in zip(back, odom, records):
        assert b.scan.stamp == scan.stamp and b.truth == truth and o.odometry == odometry
        assert (b.scan.angle_min, b.scan.angle_increment) == (scan.angle_min, scan.angle_increment)
        np.testing.assert_array_equal(b.scan.valid, scan.valid)
        np.testing.assert_allclose(b.scan.ranges[scan.valid], scan.ranges[scan.valid], atol=6e-5)


# -- the command line ------------------------------------------------------------------------------
def test_run_o_into_a_missing_folder_fails_at_once(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    monkeypatch.chdir(tmp_path)
    line = one_line_error(
        ["run", str(path), "-o", "/nonexistent/dir/x.tum"], "/nonexistent/dir/x.tum: "
    )
    assert "no folder /nonexistent/dir" in line
    assert not (tmp_path / "results").exists()  # the run never started


def test_run_refuses_another_runs_folder_unless_overwrite(sim_log, tmp_path):
    path, _run = sim_log
    out = str(tmp_path / "res")
    args = ["run", str(path), "--results", out, "--max-scans", "3"]
    assert runner.invoke(app, args).exit_code == 0
    one_line_error(args, "--overwrite")
    res = runner.invoke(app, [*args, "--overwrite"])
    assert res.exit_code == 0 and f"results in {out}/" in res.output


def test_run_default_folder_is_dated_and_printed(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["run", str(path), "--max-scans", "3"])
    assert res.exit_code == 0, res.output
    (folder,) = [p for p in (tmp_path / "results" / "sim.clf").iterdir() if p.name != "latest"]
    assert f"results in {folder.relative_to(tmp_path)}/" in res.output


def test_ctrl_c_on_run_says_so_and_keeps_the_scans_done(sim_log, tmp_path, monkeypatch):
    path, run = sim_log
    interrupt_at(monkeypatch, 6)
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--results", str(out), "-o", str(tmp_path / "x")])
    assert res.exit_code == 130 and "Traceback" not in res.output, res.output
    kept = f'the 5 scans before it are kept in {out}/ (summary.json: "partial": true)'
    assert lines_of(res) == [f"fuzzypos: interrupted at scan 6; {kept}"]
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] is True and s["partial_reason"] == "interrupted at scan 6"
    assert read_tum(out / "trajectory.tum")[0].tolist() == list(run.stamps[:5])
    assert len(list(read_carmen(out / "trajectory.clf"))) == 5
    assert not (tmp_path / "x").exists()  # -o is for a whole run
    interrupt_at(monkeypatch, 1)
    res = runner.invoke(app, ["run", str(path), "--results", str(tmp_path / "none")])
    assert res.exit_code == 130 and lines_of(res) == ["fuzzypos: interrupted; nothing kept"]
    assert not (tmp_path / "none").exists()


def test_an_error_mid_run_names_what_it_kept(sim_log, tmp_path):
    path, _run = sim_log
    lines = path.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("FLASER")) + 6
    bad = tmp_path / "bad.clf"
    bad.write_text("".join([*lines[:k], "FLASER 3 1 2\n", *lines[k:]]))
    out = tmp_path / "res"
    line = one_line_error(["run", str(bad), "--results", str(out)], "bad.clf:")
    assert line.endswith(
        f"(stopped at scan 3; the 2 scans before it are kept in {out}/ (summary.json: "
        '"partial": true))'
    )
    assert json.loads((out / "summary.json").read_text())["partial_reason"].startswith(
        "failed at scan 3: "
    )


def test_plot_scan_names_its_folder_like_the_results(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    log = tmp_path / "walk.clf.gz"
    assert runner.invoke(app, ["simulate", "--out", str(log), "--laps", "0.05"]).exit_code == 0
    res = runner.invoke(app, ["plot-scan", str(log), "--index", "2"])
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "plots" / "walk.clf-scan2").glob("fig1[3-8]_*.png"))) == 6
