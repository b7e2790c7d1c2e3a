"""``fuzzypos batch`` (fuzzypos.jobs.batch): logs × configurations as Ray tasks on a local Ray.

One Ray session serves the whole module (its start-up is slow); the first batch's results
are shared by the tests of reruns and ``--force``.
"""

from __future__ import annotations

import gzip
import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.jobs import run_batch
from fuzzypos.jobs.batch import find_logs
from fuzzypos.jobs.tasks import RayMissingError
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
    # named as a log, but random bytes: a failed run, not passed over
    (d / "noise.clf").write_bytes(np.random.default_rng(0).bytes(3000))
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
    assert names == ["broken.clf", "good.clf", "zipped.clf.gz", "noise.clf"]
    bag = make_bag(tmp_path, "ros2-sqlite3", standard)
    assert find_logs([tmp_path]) == [bag]  # a ROS2 bag directory, not the files in it
    results = tmp_path / "results" / "good.clf"
    results.mkdir(parents=True)
    (results / "trajectory.clf").write_bytes((data / "good.clf").read_bytes())
    (results / "summary.json").write_text("{}")
    assert find_logs([tmp_path]) == [bag]  # a results folder is passed over


def test_a_failed_log_does_not_stop_the_others(first: Path) -> None:
    rows = _rows(first)
    assert set(rows) == {"broken.clf", "good.clf", "noise.clf", "zipped.clf.gz"}
    for name in ("broken.clf", "noise.clf"):
        broken = rows[name]
        assert broken["status"] == "failed"
        assert name in broken["error"] and "\n" not in broken["error"]
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
    # other run options: a complete run is refused (kept) without --force, exit 1
    stamp = (first / "good.clf" / "default" / "summary.json").stat().st_mtime_ns
    res = runner.invoke(app, [*args[:-1], "6"])
    assert res.exit_code == 1, res.output
    rows = _rows(first)
    assert rows["good.clf"]["status"] == rows["zipped.clf.gz"]["status"] == "refused"
    assert f"--max-scans {MAX_SCANS} (now 6)" in rows["good.clf"]["error"]
    assert "--force" in rows["good.clf"]["error"] and "refused" in res.output
    assert (first / "good.clf" / "default" / "summary.json").stat().st_mtime_ns == stamp
    res = runner.invoke(app, [*args[:-1], "6", "--force"])
    assert res.exit_code == 1, res.output  # (the broken logs)
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
    assert kept["interrupted"] is True and kept["runs"] == 4 and len(kept["rows"]) == 1


def test_ctrl_c_exits_130(monkeypatch: pytest.MonkeyPatch, data: Path, tmp_path: Path) -> None:
    def interrupted(*args: Any, **kwargs: Any) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("fuzzypos.jobs.batch.run_batch", interrupted)
    res = runner.invoke(app, ["batch", str(data), "--out", str(tmp_path)])
    assert res.exit_code == 130 and "interrupted" in res.output
    line = f"fuzzypos: interrupted; the runs finished are in {tmp_path / 'batch.json'}"
    assert res.output.splitlines() == [line]


def test_preset_and_loop_closure_are_recorded_and_part_of_the_run(
    ray_session: None, data: Path, tmp_path: Path
) -> None:
    pytest.importorskip("gtsam", reason="loop closure needs gtsam")
    (tmp_path / "a.toml").write_text('[fuzzy]\ninference = "product"\n')
    out = tmp_path / "out"
    args = ["batch", str(data / "good.clf"), "--out", str(out), "--max-scans", "6"]
    args += ["--config", str(tmp_path / "a.toml")]
    res = runner.invoke(app, [*args, "--preset", "paper", "--loop-closure"])
    assert res.exit_code == 0, res.output
    (row,) = json.loads((out / "batch.json").read_text())["rows"]
    assert (row["status"], row["preset"], row["loop_closure"]) == ("ok", "paper", True)
    summary = json.loads((out / "good.clf" / "a" / "summary.json").read_text())
    assert summary["config"]["preset"] == "paper" and "loop_closure" in summary
    res = runner.invoke(app, [*args, "--preset", "paper", "--loop-closure"])
    assert res.exit_code == 0 and _rows(out)["good.clf"]["status"] == "skipped"
    res = runner.invoke(app, [*args, "--preset", "paper"])  # no loop closure: refused
    assert res.exit_code == 1 and _rows(out)["good.clf"]["status"] == "refused"
    assert "configuration" in _rows(out)["good.clf"]["error"]
    res = runner.invoke(app, [*args, "--loop-closure"])  # the default preset: refused
    assert res.exit_code == 1 and "preset paper" in _rows(out)["good.clf"]["error"]


def test_batch_table_keeps_errors_readable_at_80_columns() -> None:
    from rich.console import Console

    from fuzzypos.jobs.batch import batch_table

    why = "complete run with other --max-scans 2500 (now 200) kept (--force replaces it)"
    rows = [{"log": "/data/intel.clf.gz", "config": "default", "status": "refused", "error": why}]
    console = Console(width=80, record=True)
    console.print(batch_table(rows))
    text = "".join(console.export_text().split())
    assert "".join(why.split()) in "".join(text.replace("│", "").split())


RAY_QUIET = """
import sys
from fuzzypos.jobs.tasks import run_tasks


def negative(x):
    return -x


done = run_tasks(negative, [(-1,), (-2,)], jobs=1, verbose=sys.argv[1] == "verbose")
print(sorted(d.value for d in done))
"""


def test_ray_says_nothing_unless_verbose(tmp_path: Path) -> None:
    """Ray's start-up lines (its INFO "Started a local Ray instance", the token-authentication
    WARNING) are not printed but with verbose."""
    pytest.importorskip("ray", reason="Ray (the ray extra) is not installed")
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    quiet = subprocess.run(
        [sys.executable, "-c", RAY_QUIET, "quiet"], capture_output=True, text=True, env=env,
        timeout=300, cwd=tmp_path,
    )  # fmt: skip
    assert quiet.returncode == 0, quiet.stderr
    assert quiet.stdout.strip() == "[1, 2]"
    assert not re.search(r"\b(INFO|WARNING)\b", quiet.stderr), quiet.stderr
    loud = subprocess.run(
        [sys.executable, "-c", RAY_QUIET, "verbose"], capture_output=True, text=True, env=env,
        timeout=300, cwd=tmp_path,
    )  # fmt: skip
    assert loud.returncode == 0 and "INFO" in loud.stderr, loud.stderr


def test_a_rows_seconds_leave_out_the_kernels_compiling(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A new worker compiles (or loads) the kernels once: a warm-up of 2 s is the row's
    ``compile_seconds``, not part of its ``seconds``."""
    import time

    from fuzzypos.config import Config
    from fuzzypos.jobs.batch import _Run, _run_one
    from fuzzypos.pipeline import warm

    warm.compile_kernels()
    log = tmp_path / "sim.clf"
    write_sim_log(log)

    def slow_warm_up(config: Any = None, *, in_map: bool = False) -> float:
        time.sleep(2.0)
        return 2.0

    monkeypatch.setattr(warm, "compiled", lambda: True)
    monkeypatch.setattr(warm, "_compiled_in", {})  # as in a new worker process
    monkeypatch.setattr(warm, "warm_up", slow_warm_up)
    run = _Run(str(log), Config(), "default", None, str(tmp_path / "out"), None, force=False)
    t0 = time.perf_counter()
    row = _run_one(run)
    wall = time.perf_counter() - t0
    assert row["status"] == "ok", row
    assert 2.0 <= row["compile_seconds"] < 3.0
    assert row["seconds"] == pytest.approx(wall - row["compile_seconds"], abs=0.2)
    # the next run in this worker compiles nothing
    again = _run_one(_Run(str(log), Config(), "default", None, str(tmp_path / "b"), None, False))
    assert again["compile_seconds"] == 0.0
