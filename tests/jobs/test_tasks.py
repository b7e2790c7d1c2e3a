"""``fuzzypos.jobs.tasks.run_tasks`` (Ray tasks with one thread each, or one after the other here)
and what goes through it besides ``fuzzypos batch``: ``fuzzypos benchmark --jobs`` and
``benchmarks/bench_sensitivity.py``, whose Ray path gives the rows of the sequential one.

One local Ray serves the module's Ray tests (its start-up is slow); the others need no Ray.
"""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.jobs import TaskDone, run_benchmark, run_tasks
from fuzzypos.jobs.benchmark import LOOP_CLOSURE_CONFIGS
from fuzzypos.jobs.tasks import ONE_THREAD_ENV, RayMissingError, ray_installed
from helpers import write_relations, write_sim_log

runner = CliRunner()
BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
#: the keys of a benchmark row that do not depend on the machine's speed
TIMED = {"scans_per_second", "positioner_ms_per_scan", "loop_closure_seconds", "results"}


def _threads(x: int) -> tuple[int, str | None]:
    """A call's value and its thread setting (one thread in a Ray task)."""
    return x * x, os.environ.get("NUMBA_NUM_THREADS")


def _odd_fails(x: int) -> int:
    if x % 2:
        raise ValueError(f"odd: {x}")
    return x


@pytest.fixture(scope="module")
def ray_session() -> Iterator[None]:
    """A local Ray without token authentication: ``tests/jobs/test_batch_cluster.py``, run before
    in the same process, leaves Ray's driver side with authentication off, which a local Ray
    started with it on would refuse."""
    ray = pytest.importorskip("ray", reason="Ray (the ray extra) is not installed")
    if ray.is_initialized():  # pragma: no cover - another module's session
        pytest.skip("Ray is already up in this process")
    saved = os.environ.get("RAY_AUTH_MODE")
    os.environ["RAY_AUTH_MODE"] = "disabled"
    try:
        try:
            ray.init(
                address="local",
                num_cpus=2,
                include_dashboard=False,
                log_to_driver=False,
                # this module's functions go to the workers by name
                runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join(sys.path)}},
            )
        except Exception as exc:  # pragma: no cover - depends on the machine
            pytest.skip(f"Ray cannot start here: {exc}")
        yield
    finally:
        if ray.is_initialized():
            ray.shutdown()
        if saved is None:
            os.environ.pop("RAY_AUTH_MODE", None)
        else:
            os.environ["RAY_AUTH_MODE"] = saved


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small simulated log with relations beside it (a benchmark log)."""
    d = tmp_path_factory.mktemp("data") / "sim"
    d.mkdir()
    run = write_sim_log(d / "sim.clf", laps=0.08)
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    write_relations(d / "sim.relations", st, truth, [(k, k + 3) for k in range(len(st) - 3)])
    return d.parent


# -- run_tasks without Ray -------------------------------------------------------------------
def test_in_process_outcomes_in_order_errors_kept() -> None:
    seen: list[int] = []
    out = run_tasks(
        _odd_fails, [(k,) for k in range(4)], ray=False, on_done=lambda d: seen.append(d.index)
    )
    assert seen == [0, 1, 2, 3] and [d.index for d in out] == [0, 1, 2, 3]
    assert [d.value for d in out] == [0, None, 2, None]
    assert isinstance(out[1].error, ValueError) and "odd: 1" in str(out[1].error)
    assert out[2].result() == 2
    with pytest.raises(ValueError, match="odd: 3"):
        out[3].result()


def test_in_process_an_interrupt_in_on_done_stops_the_rest() -> None:
    ran: list[int] = []

    def call(x: int) -> int:
        ran.append(x)
        return x

    def stop(done: TaskDone) -> None:
        if done.index == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_tasks(call, [(k,) for k in range(5)], ray=False, on_done=stop)
    assert ran == [0, 1]


def test_bad_jobs_and_missing_ray(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ValueError, match="jobs must be at least 1"):
        run_tasks(_threads, [(1,)], ray=False, jobs=0)
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray: ImportError
    assert not ray_installed()
    with pytest.raises(RayMissingError, match=r"pip install 'fuzzypos\[ray\]'"):
        run_tasks(_threads, [(1,)])
    assert run_tasks(_threads, [(3,)], ray=False)[0].value[0] == 9  # no Ray needed


def test_benchmark_jobs_without_ray_warns_and_runs_one_after_the_other(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    args = ["benchmark", "--data", str(data), "--max-scans", "6", "--json", "--no-loop-closure"]
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "b"), "--jobs", "2"])
    assert res.exit_code == 0, res.output
    assert "fuzzypos: warning: 2 jobs need Ray (pip install 'fuzzypos[ray]')" in res.output
    rows = json.loads((tmp_path / "b" / "benchmark.json").read_text())["rows"]
    assert [r["config"] for r in rows] == ["odometry", "paper", "default"]
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "c"), "--jobs", "0"])
    assert res.exit_code == 2 and res.output.startswith("fuzzypos: error: --jobs")


# -- on Ray ----------------------------------------------------------------------------------
def test_on_ray_the_values_of_in_process_one_thread_each(ray_session: None) -> None:
    calls = [(k,) for k in range(5)]
    seen: list[int] = []
    on_ray = run_tasks(_threads, calls, on_done=lambda d: seen.append(d.index))
    here = run_tasks(_threads, calls, ray=False)
    assert [d.value[0] for d in on_ray] == [d.value[0] for d in here] == [0, 1, 4, 9, 16]
    assert {d.value[1] for d in on_ray} == {ONE_THREAD_ENV["NUMBA_NUM_THREADS"]}
    assert sorted(seen) == list(range(5))
    failed = run_tasks(_odd_fails, [(k,) for k in range(3)])
    assert [d.value for d in failed] == [0, None, 2]
    with pytest.raises(ValueError, match="odd: 1"):  # Ray's error is the task's kind too
        failed[1].result()


def test_on_ray_an_interrupt_in_on_done_propagates(ray_session: None) -> None:
    def stop(done: TaskDone) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_tasks(_threads, [(k,) for k in range(4)], on_done=stop)
    assert run_tasks(_threads, [(2,)])[0].value[0] == 4  # the session still serves


def _scores(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if k not in TIMED} for r in rows]


def test_benchmark_on_ray_gives_the_sequential_rows(
    ray_session: None, data: Path, tmp_path: Path
) -> None:
    seen: list[tuple[str, int, int | None]] = []
    here = run_benchmark(data, tmp_path / "here", max_scans=12, plot=False)
    on_ray = run_benchmark(
        data,
        tmp_path / "ray",
        max_scans=12,
        plot=False,
        jobs=2,
        progress=lambda name, done, total: seen.append((name, done, total)),
    )
    lc = [("sim.clf", c) for c in LOOP_CLOSURE_CONFIGS]  # (not scored without gtsam)
    assert [(r["log"], r["config"]) for r in on_ray.rows] == [
        ("sim.clf", "odometry"),
        ("sim.clf", "paper"),
        ("sim.clf", "default"),
        *lc,
    ]
    assert all("error" not in r and r.get("all_matched", 1) > 0 for r in on_ray.rows)
    assert _scores(on_ray.rows) == _scores(here.rows)
    assert ("sim.clf paper", 0, None) in seen and ("sim.clf default", 12, 12) in seen
    for config in ("paper", "default"):
        assert (tmp_path / "ray" / "sim.clf" / config / "summary.json").is_file()
    assert (tmp_path / "ray" / "sim.clf" / "odometry" / "trajectory.tum").is_file()


# -- benchmarks/bench_sensitivity.py ---------------------------------------------------------
def _bench_sensitivity() -> ModuleType:
    """The script as a module, not in ``sys.modules``: its functions go to Ray by value."""
    path = BENCHMARKS / "bench_sensitivity.py"
    spec = importlib.util.spec_from_file_location("bench_sensitivity", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bench_sensitivity_on_ray_gives_the_sequential_scores(
    ray_session: None, data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bench = _bench_sensitivity()
    variants = {k: bench.VARIANTS[k] for k in ("default", "iterations 12")}
    monkeypatch.setattr(bench, "VARIANTS", variants)
    pairs = bench.find_benchmark_logs(data)
    on_ray = bench.run_all(pairs, 2, True)
    here = bench.run_all(pairs, 1, False)
    assert [(lg, v) for lg, v, _, _ in on_ray] == [
        ("sim.clf", "default"),
        ("sim.clf", "iterations 12"),
    ]
    assert [s for _, _, s, _ in on_ray] == [s for _, _, s, _ in here]
    assert all(s["all_matched"] > 0 for _, _, s, _ in on_ray)


def test_bench_sensitivity_says_which_way_it_runs(
    data: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    bench = _bench_sensitivity()
    monkeypatch.setattr(bench, "VARIANTS", {"default": {}})
    monkeypatch.setitem(sys.modules, "ray", None)
    monkeypatch.setattr(sys, "argv", ["bench_sensitivity.py", "--data", str(data)])
    bench.main()
    out, err = capsys.readouterr()
    assert "Ray is not installed: the 1 runs go one after the other" in err
    assert out.splitlines()[2].startswith("| sim.clf | default | ")
