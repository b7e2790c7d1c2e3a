"""The benchmark over the shared logs: every log with a relations file next to it
(:func:`find_benchmark_logs`), run with the raw odometry, the ``paper`` preset and the
``default`` configuration (:data:`BENCHMARK_CONFIGS`), and the default with loop closure
(:data:`LOOP_CLOSURE_CONFIGS`: its optimised trajectory and its online poses), scored against
the relations (:func:`run_benchmark`), one after the other or, with ``jobs``, as Ray tasks
(:func:`~fuzzypos.jobs.tasks.run_tasks`)."""

from __future__ import annotations

import errno
import os
import warnings
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from ..config import Config
from ..eval.metrics import EvaluationError, relations_errors
from ..graph import GraphDependencyError, require_gtsam
from ..io import Relations, open_log, read_relations, write_tum
from ..io.provenance import git_hash, json_safe, write_json
from ..pipeline import warm
from .run import RunSummary, run_log
from .tasks import TaskDone, ray_installed, run_tasks

__all__ = [
    "BENCHMARK_CONFIGS",
    "BENCHMARK_LOG_NAMES",
    "LOOP_CLOSURE_CONFIGS",
    "BenchmarkResult",
    "find_benchmark_logs",
    "run_benchmark",
]

#: the runs of the benchmark, per log
BENCHMARK_CONFIGS = ("odometry", "paper", "default")

#: the rows of the loop-closure run (the default with ``[loop_closure]`` on; its front end is
#: the ``default`` row's), per log: the optimised trajectory, and each scan's pose as first
#: output online
LOOP_CLOSURE_CONFIGS = ("default+loop_closure", "default+loop_closure online")

#: the log files a relations file ``NAME.relations`` is looked for with, in this order
BENCHMARK_LOG_NAMES = ("{}.clf.gz", "{}.clf", "{}.bag")

#: ``progress(label, done, total)``
BenchmarkProgress = Callable[[str, int, "int | None"], None]

#: the runs' odometry, once one run gave it: ``(stamps, poses)``
_Odometry = tuple[np.ndarray, np.ndarray]


def find_benchmark_logs(data_dir: str | os.PathLike[str]) -> list[tuple[Path, Path]]:
    """``(log, relations)`` pairs under ``data_dir`` (searched recursively, sorted): for every
    ``NAME.relations``, each of ``NAME.clf.gz``, ``NAME.clf`` and ``NAME.bag`` next to it
    that exists (the file *names* only find the candidates; :func:`~fuzzypos.io.logs.open_log`
    then tells their kind by content). ``FileNotFoundError`` when ``data_dir`` is no
    directory."""
    root = Path(data_dir)
    if not root.is_dir():
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), os.fspath(data_dir))
    pairs: list[tuple[Path, Path]] = []
    for rel in sorted(root.rglob("*.relations")):
        if not rel.is_file():
            continue
        name = rel.name[: -len(".relations")]
        for pattern in BENCHMARK_LOG_NAMES:
            cand = rel.with_name(pattern.format(name))
            if cand.exists():
                pairs.append((cand, rel))
    return pairs


@dataclass(eq=False)
class BenchmarkResult:
    """:func:`run_benchmark`'s rows (one per log and configuration, as in ``benchmark.json``)
    and where it wrote them."""

    rows: list[dict[str, Any]]
    out_dir: Path
    json_path: Path
    data: dict[str, Any]


def _score_row(
    log_label: str, config: str, stamps: np.ndarray, poses: np.ndarray, relations: Relations
) -> dict[str, Any]:
    """A row of the benchmark: the relations metric of one trajectory, or why not scored."""
    row: dict[str, Any] = {"log": log_label, "config": config}
    try:
        row.update(relations_errors(stamps, poses, relations).as_dict())
    except EvaluationError as exc:  # e.g. no relation within a short stretch
        row["not_scored"] = str(exc)
    return row


def _run(
    log_path: Path,
    name: str,
    cfg: Config,
    preset: str,
    folder: Path,
    relations: Relations,
    *,
    max_scans: int | None,
    progress: BenchmarkProgress | None,
    plot: bool,
) -> RunSummary:
    """One run of the log with ``cfg`` (from ``preset``) into its benchmark folder, its
    progress reported as ``name``."""
    cb = None
    if progress is not None:

        def cb(done: int, total: int | None, _name: str = name) -> None:
            progress(_name, done, total)

    return run_log(
        open_log(log_path),
        cfg,
        results_dir=folder,
        overwrite=True,  # the benchmark's own folder, from its last run
        progress=cb,
        max_scans=max_scans,
        preset=preset,
        relations=relations,
        plot=plot,
    )


def _run_row(
    label: str, config: str, res: RunSummary, poses: Any, relations: Relations, folder: Path
) -> dict[str, Any]:
    """A run's row: ``poses`` scored on the relations, with the run's counts."""
    row = _score_row(label, config, res.stamps, np.asarray(poses), relations)
    row.update(
        scans=res.scans,
        scans_per_second=res.scans_per_second,
        scans_degraded=res.scans_degraded,
        odometry_jumps_rejected=res.odometry_jumps_rejected,
        results=str(folder),
    )
    return row


def _run_config(
    log_path: Path,
    label: str,
    config: str,
    folder: Path,
    relations: Relations,
    *,
    max_scans: int | None,
    progress: BenchmarkProgress | None,
    plot: bool,
) -> tuple[dict[str, Any], _Odometry | str | None]:
    """One configuration's run and row; and the odometry of its scans (or why there is none;
    None when the run failed)."""
    try:
        res = _run(
            log_path, f"{label} {config}", Config.preset(config), config, folder, relations,
            max_scans=max_scans, progress=progress, plot=plot,
        )  # fmt: skip
    except (ValueError, OSError) as exc:
        return {"log": label, "config": config, "error": str(exc)}, None
    row = _run_row(label, config, res, res.poses, relations, folder)
    row["positioner_ms_per_scan"] = 1000.0 * res.positioner_seconds / res.scans
    if res.odometry is None or not np.isfinite(res.odometry).all():
        return row, "the log has no odometry for every scan"
    return row, (res.stamps, res.odometry)


def _odometry_row(
    log_path: Path, label: str, folder: Path, odometry: _Odometry, relations: Relations
) -> dict[str, Any]:
    """Write the raw odometry's trajectory and score it."""
    folder.mkdir(parents=True, exist_ok=True)
    write_tum(
        folder / "trajectory.tum",
        odometry[0],
        odometry[1],
        header_comment=f"raw odometry of {log_path}",
    )
    row = _score_row(label, "odometry", odometry[0], odometry[1], relations)
    row.update(
        scans=int(odometry[0].size),
        scans_per_second=None,
        scans_degraded=0,
        odometry_jumps_rejected=0,
        results=str(folder),
    )
    return row


def _loop_closure_rows(
    log_path: Path,
    label: str,
    folder: Path,
    relations: Relations,
    *,
    max_scans: int | None,
    progress: BenchmarkProgress | None,
    plot: bool,
) -> list[dict[str, Any]]:
    """The loop-closure run's rows (:data:`LOOP_CLOSURE_CONFIGS`); not scored, with the
    reason, where gtsam is not installed."""
    try:
        require_gtsam()
    except GraphDependencyError as exc:
        return [{"log": label, "config": c, "not_scored": str(exc)} for c in LOOP_CLOSURE_CONFIGS]
    cfg = Config.preset("default").with_overrides({"loop_closure": {"enabled": True}})
    try:
        res = _run(
            log_path, f"{label} loop closure", cfg, "default", folder, relations,
            max_scans=max_scans, progress=progress, plot=plot,
        )  # fmt: skip
    except (ValueError, OSError) as exc:
        return [{"log": label, "config": c, "error": str(exc)} for c in LOOP_CLOSURE_CONFIGS]
    rows = []
    for config, poses in zip(LOOP_CLOSURE_CONFIGS, (res.poses, res.online_poses)):
        row = _run_row(label, config, res, poses, relations, folder)
        row["loop_closure_seconds"] = (res.loop_closure or {})["seconds"]
        rows.append(row)
    return rows


#: a warning, as it crosses from a task: ``(message, category)``
_Warning = tuple[str, type[Warning]]


def _config_task(
    log_path: Path,
    label: str,
    config: str,
    folder: Path,
    relations: Relations,
    max_scans: int | None,
    progress: BenchmarkProgress | None,
    plot: bool,
) -> tuple[list[dict[str, Any]], _Odometry | str | None, list[_Warning]]:
    """:func:`_run_config` (or, for :data:`LOOP_CLOSURE_CONFIGS`' first, the loop-closure
    run's rows, :func:`_loop_closure_rows`) as one call of :func:`run_tasks`, with the
    warnings it gave (a Ray task's would not reach the caller's warning filters)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if config == LOOP_CLOSURE_CONFIGS[0]:
            rows = _loop_closure_rows(
                log_path, label, folder, relations, max_scans=max_scans, progress=progress,
                plot=plot,
            )  # fmt: skip
            odo: _Odometry | str | None = None
        else:
            row, odo = _run_config(
                log_path, label, config, folder, relations, max_scans=max_scans,
                progress=progress, plot=plot,
            )  # fmt: skip
            rows = [row]
    return rows, odo, [(str(w.message), w.category) for w in caught]


def _log_rows(
    log_path: Path,
    label: str,
    out: Path,
    relations: Relations,
    runs: list[tuple[list[dict[str, Any]], _Odometry | str | None]],
) -> list[dict[str, Any]]:
    """The rows of one log from its runs' (paper, default): the odometry's, then each run's;
    the odometry taken from the first run that gave it (or said why there is none)."""
    odometry: _Odometry | None = None
    odometry_error: str | None = None
    for _row, odo in runs:
        if odo is not None and odometry is None and odometry_error is None:
            if isinstance(odo, str):
                odometry_error = odo
            else:
                odometry = odo
    if odometry is not None:
        orow = _odometry_row(log_path, label, out / label / "odometry", odometry, relations)
    else:
        error = odometry_error or "no run gave the odometry"
        orow = {"log": label, "config": "odometry", "error": error}
    return [orow, *(row for rows, _ in runs for row in rows)]


def _use_ray(jobs: int) -> bool:
    """Whether ``jobs`` runs at once go as Ray tasks: more than one and Ray installed (else a
    warning that they go one after the other)."""
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    if jobs == 1:
        return False
    if not ray_installed():
        warnings.warn(
            f"{jobs} jobs need Ray (pip install 'fuzzypos[ray]'); the runs go one after the "
            "other in this process",
            stacklevel=3,
        )
        return False
    return True


def run_benchmark(
    data_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    max_scans: int | None = None,
    progress: BenchmarkProgress | None = None,
    plot: bool = True,
    jobs: int = 1,
    loop_closure: bool = True,
    compiling: Callable[[], AbstractContextManager[object]] | None = None,
) -> BenchmarkResult:
    """Run every log :func:`find_benchmark_logs` finds with the raw odometry, the ``paper``
    preset and the ``default`` configuration (:data:`BENCHMARK_CONFIGS`) and score each
    against the log's relations.

    ``jobs`` 1: the runs go one after the other in this process. More: each run (a log with
    ``paper`` or ``default``) is a Ray task with one thread (:func:`~fuzzypos.jobs.tasks.run_tasks`:
    a local Ray with ``jobs`` CPUs, or the cluster of ``RAY_ADDRESS``), with the same rows;
    without Ray installed a warning, and the runs go one after the other. ``progress`` then
    reports each run at its start (``done`` 0, ``total`` None) and end (its scans), not
    scan by scan.

    Per log ``L`` (its file name), ``out_dir/L/paper/`` and ``out_dir/L/default/`` are
    :func:`~fuzzypos.jobs.run.run_log` results folders (with ``summary["relations"]``; an earlier
    benchmark's are cleared, ``overwrite=True``) and
    ``out_dir/L/odometry/trajectory.tum`` holds the raw odometry poses of the same scans
    (taken from the first run: the log is not read a third time). ``max_scans`` runs only
    the first scans of each log (relations outside them are unmatched, not scored).
    ``out_dir/benchmark.json`` holds ``fuzzypos_version``, ``git_hash``, ``data_dir``,
    ``max_scans`` and ``rows``: per log and configuration the relations metric
    (:meth:`~fuzzypos.eval.metrics.RelationsErrors.as_dict` keys: ``all_trans_mean_m``,
    ``local_rot_median_deg`` …), ``scans``, ``scans_per_second``, ``scans_degraded``,
    ``odometry_jumps_rejected``, ``results`` (the folder); ``not_scored`` (why) instead of
    the metric where no relation could be scored (e.g. none within a short stretch); and
    only ``error`` where the run failed (the other runs still go ahead).
    ``progress(label, done, total)``. ``loop_closure``: also run the default with loop closure
    into ``out_dir/L/loop_closure/`` (one more task per log) and add its rows
    (:data:`LOOP_CLOSURE_CONFIGS`: the optimised trajectory, and the online poses, with
    ``loop_closure_seconds``; ``not_scored`` where gtsam is not installed).
    ``ValueError`` when ``data_dir`` holds no log with relations. The kernels are compiled
    (or loaded) first, here (:func:`~fuzzypos.pipeline.warm.compile_kernels`, inside
    ``compiling()`` where the cache is cold; Ray's tasks on this machine then load them).
    """
    pairs = find_benchmark_logs(data_dir)
    if not pairs:
        raise ValueError(
            f"{os.fspath(data_dir)}: no log with a relations file next to it "
            "(NAME.relations with NAME.clf.gz, NAME.clf or NAME.bag)"
        )
    use_ray = _use_ray(jobs)
    warm.compile_kernels(None, compiling)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    logs: list[tuple[Path, str, Relations | str]] = []
    for log_path, rel_path in pairs:
        try:
            logs.append((log_path, log_path.name, read_relations(rel_path)))
        except (ValueError, OSError) as exc:
            logs.append((log_path, log_path.name, str(exc)))
    configs = (*BENCHMARK_CONFIGS[1:], *(LOOP_CLOSURE_CONFIGS[:1] if loop_closure else ()))
    folders = {LOOP_CLOSURE_CONFIGS[0]: "loop_closure"}
    calls = [
        (path, label, c, out / label / folders.get(c, c), rel, max_scans,
         None if use_ray else progress, plot)
        for path, label, rel in logs
        if not isinstance(rel, str)
        for c in configs
    ]  # fmt: skip

    def finished(done: TaskDone) -> None:
        rows, _, caught = done.result()  # an unexpected error stops the benchmark
        row = rows[0]
        for message, category in caught:
            warnings.warn(message, category, stacklevel=2)
        if use_ray and progress is not None:
            progress(f"{row['log']} {row['config']}", row.get("scans") or 0, row.get("scans"))

    if use_ray and progress is not None:
        for _, label, c, *_rest in calls:
            progress(f"{label} {c}", 0, None)
    outcomes = iter(run_tasks(_config_task, calls, ray=use_ray, jobs=jobs, on_done=finished))
    rows: list[dict[str, Any]] = []
    for log_path, label, rel in logs:
        if isinstance(rel, str):
            names = (*BENCHMARK_CONFIGS, *(LOOP_CLOSURE_CONFIGS if loop_closure else ()))
            rows.extend({"log": label, "config": c, "error": rel} for c in names)
            continue
        runs = [next(outcomes).result()[:2] for _ in configs]
        rows.extend(_log_rows(log_path, label, out, rel, runs))
    data = {
        "fuzzypos_version": __version__,
        "git_hash": git_hash(),
        "data_dir": os.path.abspath(os.fspath(data_dir)),
        "max_scans": max_scans,
        "rows": rows,
    }
    json_path = out / "benchmark.json"
    write_json(json_path, data)
    return BenchmarkResult(rows=rows, out_dir=out, json_path=json_path, data=json_safe(data))
