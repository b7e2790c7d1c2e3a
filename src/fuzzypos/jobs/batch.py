"""The batch job: every log under some paths × every configuration, each run one Ray task.

:func:`find_logs` tells logs by their content (:func:`~fuzzypos.io.logs.log_kind`: a ROS1 bag's
magic, a ROS2 bag directory's ``metadata.yaml``; a CARMEN file, plain or gzip, only when its
first non-comment line is a CARMEN message), passing over anything else silently, but for
a file with a log's name (``.clf``, ``.clf.gz``, ``.log``, ``.bag``: :data:`LOG_SUFFIXES`)
that it cannot read, which is kept, to fail as a run.
:func:`run_batch` runs each log with each configuration as a Ray task with one thread
(:func:`~fuzzypos.jobs.run.run_log`, results in ``<out>/<log label>/<config name>/``) and writes
``<out>/batch.json`` as runs finish: a row per run with its ``status`` (``ok``, ``failed``,
``skipped``, ``refused``), the error's first line (or why it was refused), ``seconds``
(without ``compile_seconds``, the kernels' compiling or loading in a new worker process),
``scans``, ``scans_per_second``, the ``preset`` and ``loop_closure`` it ran with and the
relations scores where a ``NAME.relations`` lies beside the log.

A run whose folder already holds complete results of the same input (sha256), configuration
(preset, file, loop closure), fuzzypos version and options is skipped unless ``force``; one
holding complete results that differ in any of them is refused (kept as it is) unless
``force``; partial or missing results are (re)made. Ray is the ``ray`` extra; without it
:class:`RayMissingError`.
"""

from __future__ import annotations

import contextlib
import gzip
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._version import __version__
from ..config import Config
from ..errors import Argument, ArgumentError, Words
from ..graph import require_gtsam
from ..io import UnknownLogError, log_kind, read_relations
from ..io.provenance import file_sha256, write_json
from .folders import log_name
from .run import run_log
from .tasks import ONE_THREAD_ENV, RayMissingError, TaskDone, require_ray, run_tasks

__all__ = [
    "BATCH_ENV",
    "BatchResult",
    "RayMissingError",
    "batch_table",
    "progress_bar",
    "find_logs",
    "run_batch",
]

#: the environment of every run's task: one thread
BATCH_ENV = ONE_THREAD_ENV
#: the first word of a CARMEN log's first non-comment line
CARMEN_MESSAGES = frozenset(
    {"FLASER", "RLASER", "ROBOTLASER1", "ROBOTLASER2", "ODOM", "TRUEPOS", "PARAM", "SYNC"}
    | {f"RAWLASER{k}" for k in range(1, 5)}
    | {"NMEAGGA", "NMEARMC", "SONAR", "BUMPER", "SCANMARK", "POSITIONLASER"}
)
#: the names of files taken for logs even where their content is not one (then a failed run)
LOG_SUFFIXES = (".clf", ".clf.gz", ".log", ".bag")
#: ``progress(row, done, total)`` as each run finishes (first ``({}, 0, total)``)
BatchProgress = Callable[[dict[str, Any], int, int], None]


# -- finding the logs ------------------------------------------------------------------------
def _first_word(path: Path) -> str | None:
    """The first word of the first non-blank, non-comment line (plain or gzip), or None."""
    try:
        with open(path, "rb") as raw:
            opener: Any = gzip.open if raw.read(2) == b"\x1f\x8b" else open
        with opener(path, "rt", encoding="utf-8", errors="replace") as f:
            for k, line in enumerate(f):
                text = line.strip()
                if text and not text.startswith("#"):
                    return str(text.split()[0])
                if k > 10_000:
                    break
    except (OSError, EOFError, UnicodeError):
        return None
    return None


def is_log(path: Path) -> bool:
    """Whether ``path`` is a log by its content (the module docstring)."""
    try:
        kind = log_kind(path)
    except (UnknownLogError, OSError):
        return False
    return kind != "carmen" or _first_word(path) in CARMEN_MESSAGES


def _walk(root: Path) -> Iterable[Path]:
    """Files and ROS2 bag directories under ``root`` (not into a bag directory), sorted; not
    into a results folder (one holding ``summary.json``: its ``trajectory.clf`` is no input)."""
    if (root / "metadata.yaml").is_file():
        yield root
        return
    if (root / "summary.json").is_file():
        return
    for child in sorted(root.iterdir()):
        if child.is_dir():
            yield from _walk(child)
        elif child.is_file():
            yield child


def find_logs(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """Every log (:func:`is_log`, or a file named as one: :data:`LOG_SUFFIXES`, whose run will
    fail where it is none) given or under the directories given, in order, once each.
    ``FileNotFoundError`` for a path that does not exist; ``ValueError`` when there is no log
    or two have the same name with its format (:func:`~fuzzypos.jobs.folders.log_name`;
    their folders would clash)."""
    found: dict[Path, None] = {}
    for given in paths:
        p = Path(given)
        if not p.exists():
            raise FileNotFoundError(2, "No such file or directory", os.fspath(given))
        for cand in _walk(p) if p.is_dir() else [p]:
            if is_log(cand) or cand.name.lower().endswith(LOG_SUFFIXES):
                found.setdefault(cand, None)
    logs = list(found)
    if not logs:
        raise ValueError(f"no log under {', '.join(os.fspath(p) for p in paths)}")
    labels: dict[str, Path] = {}
    for log in logs:
        label = log_name(log, keep_format=True)
        other = labels.setdefault(label, log)
        if other != log:
            raise ValueError(f"{other} and {log}: two logs named {label!r}")
    return logs


def relations_beside(log: Path) -> Path | None:
    """``NAME.relations`` next to the log ``NAME.clf.gz`` (``.clf``, ``.bag`` …), or None."""
    rel = log.with_name(log_name(log) + ".relations")
    return rel if rel.is_file() else None


# -- one run ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Run:
    """One task's input."""

    log: str
    config: Config
    config_name: str
    config_file: str | None
    folder: str
    max_scans: int | None
    force: bool
    preset: str = "default"
    loop_closure: bool = False


def _earlier(run: _Run) -> tuple[dict[str, Any] | None, list[str]]:
    """The folder's earlier run: its summary where it is complete (not partial, its files
    there), else None; and how it differs from ``run`` (empty: the same run)."""
    folder = Path(run.folder)
    try:
        summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
        if summary.get("partial", True) or not all(
            Path(f).exists() for f in (summary.get("files") or {}).values()
        ):
            return None, []
        made = summary.get("config") or {}
        old_scans = (summary.get("selection") or {}).get("max_scans")
        checks = [
            (summary.get("fuzzypos_version") == __version__, "fuzzypos version"),
            (old_scans == run.max_scans, f"--max-scans {old_scans} (now {run.max_scans})"),
            ((made.get("preset") or "default") == run.preset, f"preset {made.get('preset')}"),
            (made.get("file") == run.config_file, f"config file {made.get('file')}"),
            (
                (folder / "config.toml").read_text(encoding="utf-8") == run.config.to_toml(),
                "configuration (config.toml, loop closure)",
            ),
            (summary.get("input", {}).get("sha256") == file_sha256(run.log), "input"),
        ]
    except (OSError, ValueError, AttributeError):
        return None, []
    return summary, [what for same, what in checks if not same]


def _error_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def _run_one(run: _Run) -> dict[str, Any]:
    """One run's row (in the task): skipped, ok or failed."""
    t0 = time.perf_counter()
    row: dict[str, Any] = {
        "log": run.log,
        "config": run.config_name,
        "folder": run.folder,
        "status": "ok",
        "error": None,
    }
    row.update(preset=run.preset, loop_closure=run.loop_closure)
    summary, differs = (None, []) if run.force else _earlier(run)
    if summary is not None and not differs:
        row["status"] = "skipped"
    elif summary is not None:
        row.update(status="refused", error="complete run with other " + ", ".join(differs))
        row["error"] += " kept (--force replaces it)"
        summary = {}
    else:
        try:
            rel = relations_beside(Path(run.log))
            run_log(
                run.log,
                run.config,
                results_dir=run.folder,
                overwrite=True,
                max_scans=run.max_scans,
                preset=run.preset,
                config_file=run.config_file,
                relations=None if rel is None else read_relations(rel),
            )
            summary = json.loads((Path(run.folder) / "summary.json").read_text("utf-8"))
        except (ValueError, OSError) as exc:
            row.update(status="failed", error=_error_line(exc))
    summary = summary or {}
    compiling = float(summary.get("compile_seconds") or 0.0)  # once per worker: not the run's
    row.update(
        seconds=summary["seconds"]
        if row["status"] == "skipped"
        else time.perf_counter() - t0 - compiling,
        compile_seconds=0.0 if row["status"] == "skipped" else compiling,
        scans=summary.get("scans"),
        scans_per_second=summary.get("scans_per_second"),
        relations=summary.get("relations"),
    )
    return row


# -- the batch -------------------------------------------------------------------------------
@dataclass(eq=False)
class BatchResult:
    """:func:`run_batch`'s rows (as in ``batch.json``) and where it wrote them."""

    rows: list[dict[str, Any]]
    json_path: Path

    @property
    def failed(self) -> int:
        return sum(r["status"] == "failed" for r in self.rows)

    @property
    def refused(self) -> int:
        return sum(r["status"] == "refused" for r in self.rows)


def _runs(
    logs: Sequence[Path],
    configs: Sequence[Path],
    out: Path,
    max_scans: int | None,
    force: bool,
    preset: str = "default",
    loop_closure: bool = False,
) -> list[_Run]:
    """Every log × every configuration (default: the preset's), each file over ``preset``
    (as ``fuzzypos run --preset P --config FILE`` loads it), loop closure on where asked."""
    base = Config.preset(preset)
    loaded: list[tuple[str, str | None, Config]] = [
        (c.stem, str(c), Config.from_toml(c, base=None if preset == "default" else base))
        for c in configs
    ] or [(preset, None, base)]
    names = [name for name, _, _ in loaded]
    if len(set(names)) != len(names):
        raise ValueError(f"two configuration files with the same name: {names}")
    if loop_closure:
        loaded = [
            (name, file, cfg.with_overrides({"loop_closure": {"enabled": True}}))
            for name, file, cfg in loaded
        ]
    options = (max_scans, force, preset, loop_closure)
    return [
        _Run(str(log), cfg, name, file, str(out / log_name(log, keep_format=True) / name), *options)
        for log in logs
        for name, file, cfg in loaded
    ]


def _write(path: Path, rows: list[dict[str, Any]], total: int, interrupted: bool) -> None:
    data = {"fuzzypos_version": __version__, "runs": total, "interrupted": interrupted}
    write_json(path, {**data, "rows": rows})


def run_batch(
    paths: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str] = "batch",
    *,
    configs: Sequence[str | os.PathLike[str]] = (),
    max_scans: int | None = None,
    address: str | None = None,
    jobs: int | None = None,
    force: bool = False,
    progress: BatchProgress | None = None,
    preset: str = "default",
    loop_closure: bool = False,
    verbose: bool = False,
) -> BatchResult:
    """Run every log under ``paths`` (:func:`find_logs`) with every configuration file of
    ``configs`` (default: the default configuration), one Ray task each; ``batch.json`` in
    ``out`` is rewritten as each finishes. ``jobs``: the local Ray's CPUs (default: all);
    ``address``: a cluster to join. ``preset`` (``default``, ``paper``) is the configuration
    the files override (alone, it names the runs' folders); ``loop_closure`` turns on
    ``[loop_closure]`` in every run (gtsam needed); ``verbose`` lets Ray's own log lines
    through. Raises :class:`RayMissingError`, ``ValueError`` (bad
    input, a configuration file's :class:`~fuzzypos.config.ConfigError`) or ``OSError``
    before any run; ``KeyboardInterrupt`` stops the tasks, keeping what finished."""
    if jobs is not None and jobs < 1:
        raise ArgumentError(Words(Argument("jobs"), f" must be at least 1, got {jobs}"))
    if max_scans is not None and max_scans < 1:
        raise ArgumentError(Words(Argument("max_scans"), f" must be at least 1, got {max_scans}"))
    require_ray("fuzzypos batch")
    if loop_closure:
        require_gtsam()
    out_dir = Path(out)
    logs, files = find_logs(paths), [Path(c) for c in configs]
    runs = _runs(logs, files, out_dir, max_scans, force, preset, loop_closure)
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path = out_dir / "batch.json"
    rows: list[dict[str, Any]] = []

    def finished(done: TaskDone) -> None:
        run = runs[done.index]
        if done.error is None:
            row = done.value
        else:  # a crashed worker, an unexpected error in the task
            row = {"log": run.log, "config": run.config_name, "folder": run.folder}
            row.update(preset=run.preset, loop_closure=run.loop_closure)
            row.update(status="failed", error=_error_line(done.error), seconds=None, scans=None)
            row.update(scans_per_second=None, relations=None)
        rows.append(row)
        _write(json_path, rows, len(runs), False)
        if progress is not None:
            progress(row, len(rows), len(runs))

    try:
        if progress is not None:
            progress({}, 0, len(runs))
        calls = [(r,) for r in runs]
        run_tasks(_run_one, calls, jobs=jobs, address=address, on_done=finished, verbose=verbose)
    except KeyboardInterrupt:
        _write(json_path, rows, len(runs), True)
        raise
    return BatchResult(rows, json_path)


@contextlib.contextmanager
def progress_bar(console: Any) -> Iterator[BatchProgress]:
    """A :class:`BatchProgress` drawing a transient :class:`rich.progress.Progress` bar on
    ``console`` over the runs, started at the first report (errors before any run print
    nothing of it)."""
    from rich.progress import Progress

    bar = Progress(console=console, transient=True)
    task = bar.add_task("runs", total=None)
    started: list[bool] = []

    def report(row: dict[str, Any], done: int, total: int) -> None:
        if not started:
            bar.start()
            started.append(True)
        bar.update(task, completed=done, total=total)

    try:
        yield report
    finally:
        if started:
            bar.stop()


def batch_table(rows: Sequence[dict[str, Any]]) -> Any:
    """The rows as a :class:`rich.table.Table` (the error, or why a run was refused, folded
    over lines rather than cut)."""
    from rich.table import Table

    table = Table()
    for name in ("log", "config", "status", "scans", "scans/s", "s", "rel. m"):
        table.add_column(name, no_wrap=True)
    table.add_column("error / why refused", overflow="fold", ratio=1)
    for r in rows:
        rel = r.get("relations") or {}
        score = rel.get("all_trans_mean_m") if isinstance(rel, dict) else None
        sps, secs = r.get("scans_per_second"), r.get("seconds")
        table.add_row(
            log_name(r["log"], keep_format=True),
            r["config"],
            r["status"],
            "" if r.get("scans") is None else str(r["scans"]),
            "" if sps is None else f"{sps:.0f}",
            "" if secs is None else f"{secs:.1f}",
            "" if score is None else f"{score:.3f}",
            r.get("error") or "",
        )
    return table
