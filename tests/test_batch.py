"""``fuzzypos batch`` (fuzzypos.batch): logs × configurations as Ray tasks on a local Ray.

One Ray session serves the whole module (its start-up is slow); the first batch's results
are shared by the tests of reruns and ``--force``.
"""

from __future__ import annotations

import gzip
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fuzzypos.batch import RayMissingError, find_logs, run_batch
from fuzzypos.cli import app
from helpers import make_bag, standard, write_relations, write_sim_log

runner = CliRunner()
MAX_SCANS = "8"


def _rows(out: Path) -> dict[str, dict[str, Any]]:
    data = json.loads((out / "batch.json").read_text(encoding="utf-8"))
    return {Path(r["log"]).name: r for r in data["rows"]}


@pytest.fixture(scope="module")
def ray_session() -> Iterator[None]:
    ray = pytest.importorskip("ray", reason="Ray (the ray extra) is not installed")
    try:
        ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    except Exception as exc:  # pragma: no cover - depends on the machine
        pytest.skip(f"Ray cannot start here: {exc}")
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two good logs (one gzip, one with relations beside it), a broken one, and files that
    are no logs."""
    d = tmp_path_factory.mktemp("data")
    run = write_sim_log(d / "good.clf", laps=0.05)
    write_relations(d / "good.relations", run.stamps, run.true_poses, [(0, 2), (2, 4)])
    sub = d / "more"
    sub.mkdir()
    write_sim_log(sub / "plain.clf", laps=0.05, seed=3)
    with gzip.open(sub / "zipped.clf.gz", "wb") as f:
        f.write((sub / "plain.clf").read_bytes())
    (sub / "plain.clf").unlink()
    (d / "broken.clf").write_text("# a comment\nFLASER 3 1.0 2.0\n")
    (d / "README.md").write_text("# the data\nSome logs.\n")
    (d / "truth.tum").write_text("0.0 0 0 0 0 0 0 1\n")
    return d


@pytest.fixture(scope="module")
def first(ray_session: None, data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("out")
    res = runner.invoke(app, ["batch", str(data), "--out", str(out), "--max-scans", MAX_SCANS])
    assert res.exit_code == 1, res.output
    return out


def test_find_logs_by_content(data: Path, tmp_path: Path) -> None:
    names = [p.name for p in find_logs([data])]
    assert names == ["broken.clf", "good.clf", "zipped.clf.gz"]
    bag = make_bag(tmp_path, "ros2-sqlite3", standard)
    assert find_logs([tmp_path]) == [bag]  # a ROS2 bag directory, not the files in it
    results = tmp_path / "results" / "good.clf"
    results.mkdir(parents=True)
    (results / "trajectory.clf").write_bytes((data / "good.clf").read_bytes())
    (results / "summary.json").write_text("{}")
    assert find_logs([tmp_path]) == [bag]  # a results folder is passed over


def test_a_failed_log_does_not_stop_the_others(first: Path) -> None:
    rows = _rows(first)
    assert set(rows) == {"broken.clf", "good.clf", "zipped.clf.gz"}
    broken = rows["broken.clf"]
    assert broken["status"] == "failed"
    assert "broken.clf" in broken["error"] and "\n" not in broken["error"]
    for name, label in (("good.clf", "good.clf"), ("zipped.clf.gz", "zipped.clf")):
        row = rows[name]
        assert row["status"] == "ok", row
        assert row["scans"] == int(MAX_SCANS) and row["scans_per_second"] > 0
        folder = first / label / "default"
        summary = json.loads((folder / "summary.json").read_text())
        assert summary["scans"] == int(MAX_SCANS)
        poses = [ln for ln in (folder / "trajectory.tum").read_text().splitlines() if ln[0] != "#"]
        assert len(poses) == int(MAX_SCANS)
    assert rows["good.clf"]["relations"]["all_matched"] == 2
    assert rows["zipped.clf.gz"]["relations"] is None
    assert not (first / "broken.clf").exists()


def test_rerun_skips_complete_runs_and_force_redoes_them(first: Path, data: Path) -> None:
    args = ["batch", str(data), "--out", str(first), "--max-scans", MAX_SCANS]
    stamp = (first / "good.clf" / "default" / "summary.json").stat().st_mtime_ns
    res = runner.invoke(app, args)
    assert res.exit_code == 1, res.output
    rows = _rows(first)
    assert rows["good.clf"]["status"] == rows["zipped.clf.gz"]["status"] == "skipped"
    assert rows["broken.clf"]["status"] == "failed"
    assert (first / "good.clf" / "default" / "summary.json").stat().st_mtime_ns == stamp
    res = runner.invoke(app, [*args, "--force"])
    assert res.exit_code == 1, res.output
    assert _rows(first)["good.clf"]["status"] == "ok"
    assert (first / "good.clf" / "default" / "summary.json").stat().st_mtime_ns != stamp
    # other run options: not the same run
    res = runner.invoke(app, [*args[:-1], "6"])
    assert res.exit_code == 1, res.output
    rows = _rows(first)
    assert rows["good.clf"]["status"] == "ok" and rows["good.clf"]["scans"] == 6


def test_bad_input_exits_2(tmp_path: Path) -> None:
    res = runner.invoke(app, ["batch", str(tmp_path / "nothing"), "--out", str(tmp_path)])
    assert res.exit_code == 2
    assert res.output.startswith("fuzzypos: error: ") and "nothing" in res.output
    (tmp_path / "README.md").write_text("no log here\n")
    res = runner.invoke(app, ["batch", str(tmp_path)])
    assert res.exit_code == 2 and "no log under" in res.output


def test_without_ray_one_line_and_exit_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, data: Path
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray: ImportError
    with pytest.raises(RayMissingError) as info:
        run_batch([data], tmp_path)
    assert isinstance(info.value, OSError)
    res = runner.invoke(app, ["batch", str(data), "--out", str(tmp_path)])
    assert res.exit_code == 2
    assert res.output.count("\n") == 1 and "pip install 'fuzzypos[ray]'" in res.output


def test_every_log_with_every_config(first: Path, data: Path, tmp_path: Path) -> None:
    (tmp_path / "a.toml").write_text('[fuzzy]\ninference = "product"\n')
    (tmp_path / "b.toml").write_text('[fuzzy]\ninference = "mamdani"\n')
    out = tmp_path / "out"
    args = ["batch", str(data / "good.clf"), "--out", str(out), "--max-scans", "4"]
    res = runner.invoke(
        app, [*args, "--config", str(tmp_path / "a.toml"), "--config", str(tmp_path / "b.toml")]
    )
    assert res.exit_code == 0, res.output
    rows = json.loads((out / "batch.json").read_text())["rows"]
    assert sorted((r["config"], r["status"]) for r in rows) == [("a", "ok"), ("b", "ok")]
    for name in ("a", "b"):
        assert (out / "good.clf" / name / "summary.json").is_file()
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "a.toml").write_text("")
    res = runner.invoke(
        app,
        [*args, "--config", str(tmp_path / "a.toml"), "--config", str(tmp_path / "sub" / "a.toml")],
    )
    assert res.exit_code == 2 and "fuzzypos: error: " in res.output


def test_ctrl_c_keeps_what_finished(first: Path, data: Path, tmp_path: Path) -> None:
    def stop(row: dict[str, Any], done: int, total: int) -> None:
        if done == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch([data], tmp_path, max_scans=4, progress=stop)
    kept = json.loads((tmp_path / "batch.json").read_text())
    assert kept["interrupted"] is True and kept["runs"] == 3 and len(kept["rows"]) == 1


def test_ctrl_c_exits_130(monkeypatch: pytest.MonkeyPatch, data: Path, tmp_path: Path) -> None:
    def interrupted(*args: Any, **kwargs: Any) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("fuzzypos.batch.run_batch", interrupted)
    res = runner.invoke(app, ["batch", str(data), "--out", str(tmp_path)])
    assert res.exit_code == 130 and "interrupted" in res.output
