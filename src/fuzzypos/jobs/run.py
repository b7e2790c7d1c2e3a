"""The run job: running the positioner over a log and keeping the results.

:func:`run_log` streams a log (:func:`fuzzypos.io.logs.open_log`) through a
:class:`~fuzzypos.pipeline.Positioner` and writes a results folder, which holds one run: by
default a new ``results/<log>/<date-time>/`` (:func:`default_results_dir`; ``<log>`` is
:func:`log_name` with ``keep_format``: the file name without a compression suffix) with
``results/<log>/latest`` linked to it; a folder given that holds another run's results is
refused, or with ``overwrite=True`` cleared first (:class:`ResultsFolderError`); the run locks
it until it ends. A run stopped by an error or Ctrl-C after some scans keeps them: the files
below (but ``path.png``) for the scans done, ``summary.json`` saying ``"partial": true`` and
why (:func:`partial_results`); so does one stopped after its loop (loop closure's final
optimisation: the front end's poses are written; a writer: the other files are), each step
after the loop a :class:`~fuzzypos.jobs.outputs.Steps` step.

================  ==========================================================================
``trajectory.tum``  the estimated pose of every scan, ``t x y z qx qy qz qw``, one line per
                    scan in file order, ``t`` the scan's stamp as the log gives it at full
                    precision (``repr``, never rounded: intel has scans < 2 ms apart)
``trajectory.clf``  the log again as CARMEN ``FLASER`` lines (:func:`write_estimate_clf`):
                    the ``x y θ`` fields carry the estimate, ``odom_x odom_y odom_θ`` the
                    log's odometry; ``ROBOTLASER1`` lines (the estimate as the robot pose,
                    the odometry in an ``ODOM`` line) for scans FLASER cannot describe;
                    ``TRUEPOS`` lines where the log had truth
``config.toml``     the configuration used (:meth:`~fuzzypos.config.Config.to_toml`; it
                    loads back with :meth:`~fuzzypos.config.Config.from_toml`)
``path.png``        the estimated path and the odometry over a map of every
                    ``map_every``-th scan's points placed by the estimate
``covariance.csv``  a header line, then one row per scan (:data:`COVARIANCE_COLUMNS`,
                    comma-separated): the stamp (``repr``, as in ``trajectory.tum``); the six
                    entries ``xx xy xθ yy yθ θθ`` of the step's (the increment's) covariance
                    (:attr:`~fuzzypos.pipeline.Estimate.covariance`, in the previous scan's
                    frame); the same six of the pose's covariance ``pose_xx … pose_θθ``, the
                    steps' propagated from the first scan and turned into the trajectory
                    frame, as the bag's (below); the :class:`~fuzzypos.pipeline.Reason`
                    (``reason``, its value, quoted where it has a comma) and ``degraded``
                    (0/1). Left out with a note where the positioner gives no covariance
``summary.json``    what ran on what, how fast, how well (:func:`run_log`), and why:
                    ``reasons``, the scans per :class:`~fuzzypos.pipeline.Reason` (by its
                    value, each that occurred); ``odometry_noise``, the odometry's noise as
                    learned by the end of the run
                    (:meth:`~fuzzypos.pipeline.OdometryNoise.as_dict`); the "no return"
                    codes found in the log's readings (:func:`_no_returns`)
================  ==========================================================================

With ``bag_out=`` the estimate also goes into a bag as it runs (:class:`_CovarianceOut`,
:class:`~fuzzypos.io.OdometryBagWriter`): ``nav_msgs/Odometry`` on ``/fuzzypos/odom`` and
``/tf`` (odom → base), in REP-105 frames (``bag_frames``, else the input bag's, else
``base_link``, ``odom``, ``map``; ``summary.json``'s ``bag_out``). The pose's covariance is
the increments' propagated from the first scan (:func:`~fuzzypos.geometry.propagate`; the
first pose's covariance is the first estimate's), turned into the odom frame
(:func:`~fuzzypos.geometry.covariance_to_parent`); the twist is the increment over the time
since the previous scan (its covariance the increment's over dt²), zero with unknown
covariance at the first scan and where dt <= 0. With loop closure the optimised poses follow
on ``/fuzzypos/pose`` (map frame, their covariance the pose graph's marginals carried to
each scan and rotated into the map frame, as in ``covariance_optimised.csv``:
:func:`~fuzzypos.graph.outputs.optimised_covariances`) with map → odom on ``/tf``.

Memory stays small on long logs: only the stamps and poses (estimate, odometry, truth)
and the points of every ``map_every``-th scan are kept, never the scans.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from ..config import Config
from ..eval.metrics import EvaluationError, relations_errors, trajectory_errors
from ..geometry import Pose2D
from ..graph import LoopClosureResult, OnlineMapper, require_gtsam
from ..graph.occupancy import MapScans, map_grid
from ..io import CarmenWriter, LogRecord, OpenLog, Relations, open_log, write_text_file, write_tum
from ..io.bag_info import OutputFrames
from ..io.logs import empty_stretch, select_records, select_stamps, survey_log
from ..io.no_returns import with_found_bands
from ..io.odometry_check import OdometryCoverage
from ..io.provenance import file_sha256, git_hash, write_json
from ..pipeline import Positioner, Reason, warm
from ..scan import LaserScan
from .folders import (
    RESULT_FILES,
    ResultsFolder,
    ResultsFolderError,
    check_outputs,
    default_results_dir,
    log_name,
)
from .outputs import (
    COVARIANCE_COLUMNS,
    POSE_COVARIANCE_COLUMNS,
    STEP_COVARIANCE_COLUMNS,
    Steps,
    _CovarianceOut,
    as_interrupt,
    is_interrupt,
    one_line,
    resolve_bag_frames,
)

__all__ = [
    "COVARIANCE_COLUMNS",
    "POSE_COVARIANCE_COLUMNS",
    "RESULT_FILES",
    "STEP_COVARIANCE_COLUMNS",
    "Progress",
    "ResultsFolderError",
    "RunSummary",
    "as_interrupt",
    "default_results_dir",
    "is_interrupt",
    "partial_results",
    "run_log",
    "write_estimate_clf",
]

#: ``progress(done, total)`` (``total`` None when unknown)
Progress = Callable[[int, "int | None"], None]

#: where :func:`partial_results` finds what a stopped run kept
_PARTIAL = "fuzzypos_partial_results"

#: how often (in scans) :func:`run_log` reports its progress
_PROGRESS_EVERY = 25

Row = tuple[float, float, float]


def partial_results(exc: BaseException) -> RunSummary | None:
    """What :func:`run_log` kept of a run that ``exc`` stopped after some scans (its results
    folder, ``summary.json`` marked partial), or None."""
    kept = exc.__dict__.get(_PARTIAL)
    return kept if isinstance(kept, RunSummary) else None


def _scans_in_stretch(
    log: OpenLog, start: float | None, end: float | None, max_scans: int | None
) -> int | None:
    """The scans of the stretch, for the progress bar: the whole log's count, or with
    ``start``/``end`` those its scans' stamps put in the stretch
    (:meth:`~fuzzypos.io.logs.OpenLog.scan_stamps`, a quick pass); None when unknown."""
    total: int | None = None
    if start is None and end is None:
        total = log.scan_count_hint()
    else:
        with contextlib.suppress(OSError):
            total = len(select_stamps(log.scan_stamps(), start=start, end=end))
    if max_scans is not None:
        total = max_scans if total is None else min(total, max_scans)
    return total


# -- the estimate as a CARMEN log --------------------------------------------------------------
def write_estimate_clf(
    path: str | os.PathLike[str],
    records: Iterable[tuple[LaserScan, Pose2D, Pose2D | None, Pose2D | None]],
    *,
    source: str = "",
) -> int:
    """Write ``(scan, estimate, odometry, truth)`` tuples as a CARMEN log; return the lines
    written.

    One ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_timestamp hostname
    logger_timestamp`` line per scan, in the order given: ``x y θ`` = the estimate,
    ``odom_*`` = the odometry (the estimate where it is None), both timestamps the scan's
    stamp (``repr``); then ``TRUEPOS`` when ``truth`` is given. Ranges are the scan's raw
    readings to 0.1 mm (NaN, ±inf and absurd ones as read, ``nan``, ``inf``, ``1e+308``,
    which read back invalid). Unlike
    :func:`fuzzypos.io.write_carmen` (which writes the odometry into both pose fields and
    needs one ``range_max`` for the whole log) this streams any log the readers give: the
    beam geometry is taken from the first scan (field of view and convention in a header
    comment; scans that do not fit it are left out and counted in a note) and the maximum
    range is left for the reader to learn. Written to a temporary file first, so a failure
    leaves no partial file; plain text whatever the name. Both are
    :class:`~fuzzypos.io.CarmenWriter` (here with ``estimate_of=source``).
    """
    w = CarmenWriter(path, estimate_of=source, compress=False)
    try:
        for scan, est, odom, truth in records:
            w.write(scan, odom, truth, pose=est)
    except BaseException:
        w.abort()
        raise
    w.close()
    return w.written


# -- one run ---------------------------------------------------------------------------------
@dataclass(eq=False)
class RunSummary:
    """What :func:`run_log` did.

    ``stamps`` ``(n,)``, ``poses`` ``(n, 3)`` (the estimate), ``odometry`` ``(n, 3)`` or None
    (NaN rows for scans without odometry), ``truth`` likewise; ``files``: name → path of
    what was written; ``summary``: the content of ``summary.json``.
    """

    results_dir: Path
    scans: int
    scans_degraded: int
    odometry_jumps_rejected: int
    seconds: float
    positioner_seconds: float
    stamps: np.ndarray
    poses: np.ndarray
    odometry: np.ndarray | None
    truth: np.ndarray | None
    files: dict[str, Path]
    summary: dict[str, Any]
    notes: list[str] = field(default_factory=list)
    #: with loop closure: each scan's pose as first output online, and the front end's
    online_poses: np.ndarray | None = None
    frontend_poses: np.ndarray | None = None
    #: the kernels' compiling (or loading) before the first scan, not in the figures above
    compile_seconds: float = 0.0

    @property
    def scans_per_second(self) -> float:
        return self.scans / self.seconds if self.seconds > 0 else float("nan")


def _pose_rows(poses: list[Row | None]) -> np.ndarray | None:
    if not any(p is not None for p in poses):
        return None
    nan = (math.nan, math.nan, math.nan)
    return np.array([p if p is not None else nan for p in poses], dtype=np.float64).reshape(-1, 3)


def _row(p: Pose2D | None) -> Row | None:
    return None if p is None else (p.x, p.y, p.theta)


@dataclass(eq=False)
class _Track:
    """What the run keeps of each scan (never the scan itself), and its timing."""

    stamps: list[float] = field(default_factory=list)
    poses: list[Row] = field(default_factory=list)
    odoms: list[Row | None] = field(default_factory=list)
    truths: list[Row | None] = field(default_factory=list)
    map_points: list[np.ndarray | None] = field(default_factory=list)
    degraded: int = 0
    #: the scans per reason (:class:`~fuzzypos.pipeline.Reason`'s value)
    reasons: dict[str, int] = field(default_factory=dict)
    positioner_seconds: float = 0.0
    seconds: float = 0.0
    compile_seconds: float = 0.0
    #: what stopped the run before the end of the stretch (an error, Ctrl-C), and why
    stopped: BaseException | None = None
    partial_reason: str | None = None
    #: loop closure online (loop closure on): the pose graph of the keyframes, with their
    #: features, and the scans kept for the map
    mapper: OnlineMapper | None = None
    #: ``save_map`` without loop closure: the scans the map is drawn from
    map_scans: MapScans | None = None

    def __len__(self) -> int:
        return len(self.stamps)


def _position_along(
    records: Iterator[LogRecord],
    positioner: Positioner,
    clf: CarmenWriter,
    outputs: _CovarianceOut,
    plot: bool,
    map_every: int,
    progress: Progress | None,
    total: int | None,
    save_map: bool = False,
) -> _Track:
    """Run ``positioner`` over ``records``, streaming the estimate into ``clf`` and
    ``outputs`` and keeping the :class:`_Track` of the scans done. An error or Ctrl-C stops
    the run: it is kept in ``track.stopped`` (anything else aborts both and is raised).
    ``save_map`` (without loop closure, whose mapper keeps its own): keep the map's scans."""
    cfg = positioner.config
    track = _Track(mapper=OnlineMapper(cfg) if cfg.loop_closure.enabled else None)
    lc = cfg.loop_closure
    if save_map and track.mapper is None:
        track.map_scans = MapScans(lc.map_scan_distance, lc.map_scan_angle)
    bands = positioner.config.scanner.no_return_bands  # the map shows what the positioner saw
    t_start = time.perf_counter()
    try:
        for k, rec in enumerate(records):
            scan, odom = rec.scan, rec.odometry
            t0 = time.perf_counter()
            est = positioner.update(scan, odom)
            track.positioner_seconds += time.perf_counter() - t0
            pose = est.pose
            outputs.write(k, est)
            if track.mapper is not None:
                track.mapper.add(est, scan.angle_increment)
            elif track.map_scans is not None:
                points = None if est.features is None else est.features.points
                track.map_scans.add(k, est.pose.as_array(), points)
            clf.write(scan, odom, rec.truth, pose=pose)
            track.stamps.append(scan.stamp)
            track.poses.append((pose.x, pose.y, pose.theta))
            track.odoms.append(_row(odom))
            track.truths.append(_row(rec.truth))
            track.degraded += bool(est.degraded)
            why = str(est.reason)
            track.reasons[why] = track.reasons.get(why, 0) + 1
            if plot:
                track.map_points.append(scan.points_robot(bands) if k % map_every == 0 else None)
            if progress is not None and (k + 1) % _PROGRESS_EVERY == 0:
                progress(k + 1, total)
    except (Exception, KeyboardInterrupt) as exc:
        stopped = as_interrupt(exc)  # numba's SystemError around Ctrl-C: Ctrl-C
        track.stopped = stopped
        at = f"scan {len(track) + 1}"
        what = one_line(stopped)
        interrupted = isinstance(stopped, KeyboardInterrupt)
        track.partial_reason = f"interrupted at {at}" if interrupted else f"failed at {at}: {what}"
    except BaseException:
        clf.abort()
        outputs.abort()
        raise
    track.seconds = time.perf_counter() - t_start
    return track


def _no_scans(log: OpenLog, start: float | None, end: float | None) -> ValueError:
    if start is not None or end is not None:
        stretch = empty_stretch(log, start, end)
        if stretch is not None:  # the log has scans, but not there
            return stretch
    hint = " (is it a CARMEN log with FLASER or ROBOTLASER1 lines?)" if log.kind == "carmen" else ""
    return ValueError(f"{log.name}: no scans{hint}")


def _plot_path(
    path: Path,
    log: OpenLog,
    poses: np.ndarray,
    odometry: np.ndarray | None,
    map_points: list[np.ndarray | None],
    map_every: int,
) -> None:
    from ..plot import figures as plotting  # matplotlib only when figures are made

    odo_xy = None if odometry is None else odometry[np.isfinite(odometry).all(axis=1)]
    plotting.plot_map(
        poses,
        map_points,
        odometry=odo_xy,
        path=path,
        title=f"{log_name(log.name)}: estimated path, odometry and map (scans 1 in {map_every})",
    )


def _truth_errors(
    truth: np.ndarray | None, poses: np.ndarray, odometry: np.ndarray | None, degraded: int
) -> dict[str, Any] | None:
    """The estimate's (and the odometry's) errors against the log's truth, where every scan
    has one."""
    if truth is None or not np.isfinite(truth).all():
        return None
    out: dict[str, Any] = {"estimate": trajectory_errors(truth, poses, degraded).as_dict()}
    if odometry is not None and np.isfinite(odometry).all():
        out["odometry"] = trajectory_errors(truth, odometry, 0).as_dict()
    return out


def _relations_errors(
    stamps: np.ndarray, poses: np.ndarray, relations: Relations | None, notes: list[str]
) -> dict[str, Any] | None:
    if relations is None:
        return None
    try:
        rel: dict[str, Any] = relations_errors(stamps, poses, relations).as_dict()
    except EvaluationError as exc:
        notes.append(f"relations: {exc}")
        return None
    return rel


@dataclass(eq=False)
class _Arrays:
    """The track as arrays: stamps, estimate, odometry and truth (NaN rows where missing)."""

    stamps: np.ndarray
    poses: np.ndarray
    odometry: np.ndarray | None
    truth: np.ndarray | None

    @classmethod
    def of(cls, track: _Track) -> _Arrays:
        return cls(
            stamps=np.array(track.stamps, dtype=np.float64),
            poses=np.array(track.poses, dtype=np.float64).reshape(-1, 3),
            odometry=_pose_rows(track.odoms),
            truth=_pose_rows(track.truths),
        )


def _write_results(
    out: Path,
    log: OpenLog,
    cfg: Config,
    a: _Arrays,
    track: _Track,
    clf: CarmenWriter,
    *,
    outputs: _CovarianceOut,
    out_tum: str | os.PathLike[str] | None,
    plot: bool,
    map_every: int,
    steps: Steps,
    loop: LoopClosureResult | None = None,
) -> dict[str, Path]:
    """Write the results folder's files but ``summary.json``; name → path of those written,
    in writing order. Each is a step (:class:`Steps`): one that fails or is interrupted
    makes the run partial, and the others are still written but ``path.png`` and
    ``out_tum``, which a partial run does not get. ``loop``: loop closure's result, whose
    poses ``a.poses`` are and ``trajectory.clf`` then carries."""
    files: dict[str, Path] = {}
    optimised = None if loop is None else (a.stamps, loop.poses, loop.frontend, loop.covariances)

    def tum() -> dict[str, Path]:
        what = "part of the" if steps.partial else "the"
        comment = f"fuzzypos {__version__}: {what} estimate of {log.name} (t = the scan's stamp)"
        write_tum(out / "trajectory.tum", a.stamps, a.poses, header_comment=comment)
        return {"trajectory.tum": out / "trajectory.tum"}

    def out_file() -> dict[str, Path]:
        assert out_tum is not None
        comment = f"fuzzypos {__version__} estimate of {log.name}"
        write_tum(out_tum, a.stamps, a.poses, header_comment=comment)
        return {"out_tum": Path(out_tum)}

    def trajectory_clf() -> dict[str, Path]:
        why = "x y theta after loop closure: the optimised poses" if loop is not None else ""
        kept = clf.close(a.poses if loop is not None else None, why)
        return {"trajectory.clf": out / "trajectory.clf"} if kept else {}

    def config_toml() -> dict[str, Path]:
        write_text_file(out / "config.toml", cfg.to_toml())
        return {"config.toml": out / "config.toml"}

    def path_png() -> dict[str, Path]:
        _plot_path(out / "path.png", log, a.poses, a.odometry, track.map_points, map_every)
        return {"path.png": out / "path.png"}

    def loop_files() -> dict[str, Path]:
        assert loop is not None
        return loop.write(out, a.stamps, log.name, cfg.loop_closure.map_resolution)

    def map_files() -> dict[str, Path]:
        assert track.map_scans is not None
        grid = map_grid(a.poses, track.map_scans.scans, cfg.loop_closure.map_resolution)
        return grid.write(out)

    for what, write, whole_runs_only in (
        ("trajectory.tum", tum, False),
        ("covariance.csv", outputs.close_csv, False),
        ("the bag", lambda: outputs.close_bag(partial=steps.partial, optimised=optimised), False),
        (os.fspath(out_tum or ""), out_file if out_tum is not None else None, True),
        ("trajectory.clf", trajectory_clf, False),
        ("config.toml", config_toml, False),
        ("path.png", path_png if plot else None, True),
        ("loop closure's files", loop_files if loop is not None else None, False),
        ("the map", map_files if track.map_scans is not None else None, False),
    ):
        if write is not None and not (whole_runs_only and steps.partial):
            files.update(steps.run(f"while writing {what}", write) or {})
    steps.notes.extend([*outputs.notes, *clf.notes])
    if steps.partial:
        missing = [] if "path.png" in files else ["no path.png"]
        if out_tum is not None and "out_tum" not in files:
            missing.append(f"{out_tum} was not written")
        steps.notes.append("a partial run" + (": " + ", and ".join(missing) if missing else ""))
    return files


def _summary(
    log: OpenLog,
    track: _Track,
    a: _Arrays,
    *,
    jumps: int,
    selection: dict[str, Any],
    config: dict[str, Any],
    hash_input: bool,
    truth_errors: dict[str, Any] | None,
    relations: dict[str, Any] | None,
    notes: list[str],
    files: dict[str, Path],
    odometry_noise: dict[str, Any],
) -> dict[str, Any]:
    """The content of ``summary.json`` (:func:`run_log`)."""
    n, seconds = len(track), track.seconds
    return {
        "fuzzypos_version": __version__,
        "git_hash": git_hash(),
        "input": {
            "path": os.path.abspath(log.name),
            "sha256": file_sha256(log.path) if hash_input else None,
            "kind": log.kind,
            "options": log.options,
        },
        "selection": selection,
        "partial": track.partial_reason is not None,
        "partial_reason": track.partial_reason,
        "scans": n,
        "scans_degraded": track.degraded,
        "reasons": _reason_counts(track.reasons),
        "odometry_noise": odometry_noise,
        "odometry_jumps_rejected": jumps,
        "seconds": seconds,
        "scans_per_second": n / seconds if seconds > 0 else None,
        "positioner_seconds": track.positioner_seconds,
        "positioner_ms_per_scan": 1000.0 * track.positioner_seconds / n,
        "compile_seconds": track.compile_seconds,
        "config": config,
        "bad_lines_skipped": log.bad_lines,
        "truncated": log.truncated,
        "scan_rate_hz": log.scan_rate_hz,
        "first_stamp": track.stamps[0],
        "last_stamp": track.stamps[-1],
        "has_odometry": a.odometry is not None,
        "has_truth": a.truth is not None,
        "truth_errors": truth_errors,
        "relations": relations,
        "notes": notes,
        "files": {k: str(v) for k, v in files.items()},
    }


def _reason_counts(counts: dict[str, int]) -> dict[str, int]:
    """The scans per reason, in :class:`~fuzzypos.pipeline.Reason`'s order (any other after)."""
    order = [r.value for r in Reason if r.value in counts]
    return {why: counts[why] for why in [*order, *(w for w in counts if w not in order)]}


def _final_optimisation(track: _Track, steps: Steps) -> tuple[_Arrays, LoopClosureResult | None]:
    """The track as arrays, with loop closure's optimised poses once its final optimisation
    (a step) is done; the front end's where it did not finish, or the run is partial."""
    a = _Arrays.of(track)
    if track.mapper is None or steps.partial:
        return a, None
    loop = steps.run("in loop closure's final optimisation", track.mapper.finish)
    if loop is None:
        steps.notes.append(
            "loop closure did not finish: trajectory.tum holds the front end's poses"
        )
        return a, None
    steps.notes.append(
        "loop closure: trajectory.tum holds the optimised poses (trajectory_frontend.tum "
        "the front end's, trajectory_online.tum each scan's as first output online) and "
        "so does trajectory.clf; covariance.csv and the bag's odometry are the front end's "
        "(a bag gets the optimised poses and map -> odom too), covariance_optimised.csv the "
        "optimised poses' covariances (the pose graph's marginals)"
    )
    if loop.covariances is None:
        steps.notes.append(
            "no covariance_optimised.csv: gtsam gave no marginals "
            f"({loop.summary.get('marginals_error')}); the bag's optimised poses' covariance "
            "is unknown"
        )
    return replace(a, poses=loop.poses), loop


def _finish(
    out: Path,
    log: OpenLog,
    cfg: Config,
    track: _Track,
    clf: CarmenWriter,
    outputs: _CovarianceOut,
    *,
    positioner: Positioner,
    labels: dict[str, Any],
    out_tum: str | os.PathLike[str] | None,
    relations: Relations | None,
    plot: bool,
    map_every: int,
    hash_input: bool,
    progress: Progress | None,
    compile_seconds: float = 0.0,
) -> RunSummary:
    """After the loop: loop closure's final optimisation, the results folder
    (``summary.json`` last), the run summed up (``compile_seconds``: the kernels' before the
    loop). Each is a step (:class:`Steps`): one that fails or is interrupted makes the run
    partial (``track.stopped``, ``partial_reason``) and the rest is still done; where loop
    closure did not finish, its files are not written and ``trajectory.tum`` and
    ``trajectory.clf`` hold the front end's poses."""
    jumps = int(positioner.odometry_jumps)
    track.compile_seconds = compile_seconds
    notes = list(dict.fromkeys([*log.notes, *getattr(log.reader, "notes", [])]))
    steps = Steps(track.stopped, track.partial_reason, notes)
    n = len(track)
    if progress is not None and not steps.partial:
        steps.run("after the last scan", lambda: progress(n, n))
    a, loop = _final_optimisation(track, steps)
    files = _write_results(
        out, log, cfg, a, track, clf, outputs=outputs, out_tum=out_tum, plot=plot,
        map_every=map_every, steps=steps, loop=loop,
    )  # fmt: skip
    truth_errors = steps.run(
        "scoring against the truth",
        lambda: _truth_errors(a.truth, a.poses, a.odometry, track.degraded),
    )
    rel = steps.run(
        "while scoring against the relations",
        lambda: _relations_errors(a.stamps, a.poses, relations, notes),
    )
    loop_rel = {}
    if loop is not None and relations is not None and loop.online is not None:
        for name, poses in (("frontend", loop.frontend), ("online", loop.online)):
            loop_rel[f"relations_{name}"] = steps.run(
                "while scoring against the relations",
                functools.partial(_relations_errors, a.stamps, poses, relations, notes),
            )
    track.stopped, track.partial_reason = steps.stop, steps.reason
    files["summary.json"] = out / "summary.json"
    summary = _summary(
        log,
        track,
        a,
        jumps=jumps,
        selection=labels["selection"],
        config=labels["config"],
        hash_input=hash_input,
        truth_errors=truth_errors,
        relations=rel,
        notes=notes,
        files=files,
        odometry_noise=positioner.odometry_noise.as_dict(),
    )
    summary["no_return_values_found"] = labels["no_return_values_found"]
    summary["bag_out"] = outputs.bag_summary()
    coverage = labels["odometry_coverage"]
    summary["odometry_coverage"] = coverage.as_dict()
    if coverage.note() is not None and coverage.note() not in notes:
        notes.append(coverage.note())
    if loop is not None:
        summary["loop_closure"] = {**loop.summary, **loop_rel}
    if not steps.done(
        "while writing summary.json", lambda: write_json(out / "summary.json", summary)
    ):
        del files["summary.json"]
    track.stopped, track.partial_reason = steps.stop, steps.reason
    return RunSummary(
        results_dir=out,
        scans=len(track),
        scans_degraded=track.degraded,
        odometry_jumps_rejected=jumps,
        seconds=track.seconds,
        positioner_seconds=track.positioner_seconds,
        compile_seconds=track.compile_seconds,
        stamps=a.stamps,
        poses=a.poses,
        odometry=a.odometry,
        truth=a.truth,
        files=files,
        summary=summary,
        notes=notes,
        online_poses=None if loop is None else loop.online,
        frontend_poses=None if loop is None else loop.frontend,
    )


def run_log(
    log: OpenLog | str | os.PathLike[str],
    config: Config | None = None,
    *,
    results_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    out_tum: str | os.PathLike[str] | None = None,
    progress: Progress | None = None,
    start: float | None = None,
    end: float | None = None,
    max_scans: int | None = None,
    preset: str | None = None,
    config_file: str | os.PathLike[str] | None = None,
    relations: Relations | None = None,
    map_every: int = 10,
    plot: bool = True,
    hash_input: bool = True,
    bag_out: str | os.PathLike[str] | None = None,
    bag_storage: str | None = None,
    bag_frames: Mapping[str, str | None] | None = None,
    save_map: bool = False,
    compiling: Callable[[], contextlib.AbstractContextManager[object]] | None = None,
) -> RunSummary:
    """Position the robot along ``log`` (an :class:`~fuzzypos.io.logs.OpenLog`, or a path opened
    with :func:`~fuzzypos.io.logs.open_log`'s defaults) and write a results folder:
    ``trajectory.tum``, ``trajectory.clf``, ``config.toml``, ``path.png`` (unless
    ``plot=False``) and ``summary.json`` and ``covariance.csv`` (module docstring); with
    ``save_map``, the front end's occupancy map (:mod:`fuzzypos.graph.occupancy`).
    ``results_dir``: the folder (one holding another run's results is a
    :class:`~fuzzypos.jobs.folders.ResultsFolderError` unless ``overwrite`` clears it); None: a new
    ``results/<log>/<date-time>/`` (:mod:`fuzzypos.jobs.folders`). ``out_tum``: also write the
    trajectory there. ``bag_out``: also write the estimate into a new bag there (module
    docstring; an existing path is a :class:`FileExistsError`), ``bag_storage`` and
    ``bag_frames`` (:func:`~fuzzypos.jobs.outputs.resolve_bag_frames`). All checked first.

    ``start``, ``end``, ``max_scans`` choose a stretch (:func:`~fuzzypos.io.logs.select_records`).
    ``preset`` and ``config_file`` only label the configuration in ``summary.json``.
    ``relations``: also score the trajectory against them (``summary["relations"]``).
    ``progress(done, total)`` is called every 25 scans and at the end (``total``: the scans the
    stretch can have at most, when known: a bag's stretch by time is not). The kernels compile
    (or load) first, in ``compiling()`` if cold (:func:`~fuzzypos.pipeline.warm.compile_kernels`).

    ``summary.json`` holds: ``fuzzypos_version``, ``git_hash``
    (:func:`~fuzzypos.io.provenance.git_hash`), ``input`` (``path``, ``sha256``
    (:func:`~fuzzypos.io.provenance.file_sha256`; None with ``hash_input=False``), ``kind``, reader
    ``options``), ``selection``, ``scans``, ``scans_degraded``, ``reasons``, ``odometry_noise``
    (module docstring), ``odometry_jumps_rejected``, ``seconds`` (the whole loop: reading,
    positioning, writing), ``scans_per_second`` (``scans / seconds``), ``positioner_seconds``
    and ``positioner_ms_per_scan`` (inside :meth:`Positioner.update` only), ``compile_seconds``
    (the kernels' before the run, in neither), ``config`` (``preset``, ``file``),
    ``bad_lines_skipped``, ``first_stamp``/``last_stamp``,
    ``has_odometry``, ``truth_errors`` (:func:`~fuzzypos.eval.metrics.trajectory_errors` of the
    estimate and of the odometry against the log's ``TRUEPOS``, where every scan has one; else
    None), ``relations`` (or None), ``no_return_values_found``, ``notes``, ``files``, and
    ``partial`` (False) with ``partial_reason`` (None), ``scan_rate_hz`` (the log's
    :attr:`~fuzzypos.io.logs.OpenLog.scan_rate_hz`), ``odometry_coverage``
    (:meth:`~fuzzypos.io.odometry_check.OdometryCoverage.as_dict`: the scans the odometry does
    not cover are positioned without it, with a note), ``bag_out`` (the bag's frames and
    topics, or None). Loop closure: ``loop_closure``, the optimised poses.

    Raises ``ValueError`` (bad arguments, a log without scans in the stretch, a malformed
    log) or ``OSError`` (an output path refused before the run:
    :class:`~fuzzypos.io.OutputPathError`; a folder another run holds:
    :class:`~fuzzypos.jobs.folders.ResultsFolderBusyError`). An error or ``KeyboardInterrupt``
    (numba's ``SystemError`` around one too) after some scans is raised once what was done is
    written (``"partial": true``, ``"partial_reason"``: ``"interrupted at scan N"``, ``"failed
    at scan N: …"``, or after the loop ``"interrupted in loop closure's final optimisation"``,
    ``"failed while writing F: No space left on device"`` …; no ``path.png`` or ``out_tum``
    after it; their :class:`RunSummary`: :func:`partial_results`); before it, nothing kept.
    """
    if not isinstance(log, OpenLog):
        log = open_log(log)
    cfg, found, coverage = _survey(log, config if config is not None else Config())
    _check_map_every(map_every)
    stretch: dict[str, Any] = {"start": start, "end": end, "max_scans": max_scans}
    records = select_records(coverage.records(log.records()), **stretch)
    log.check_stamps(**stretch)  # corrupt stamps: StampError
    total = _scans_in_stretch(log, start, end, max_scans) if progress is not None else None
    positioner = Positioner(cfg)
    given = None if results_dir is None else Path(results_dir)
    frames = None if bag_out is None else resolve_bag_frames(log.reader, bag_frames)
    compile_seconds = _before_the_run(cfg, given, out_tum, bag_out, compiling)
    folder = ResultsFolder.make(log.name, given, overwrite)
    with folder:  # locked by this run until it ends
        clf, outputs = _open_outputs(folder, log.name, bag_out, bag_storage, frames)
        track = _position_along(
            records, positioner, clf, outputs, plot, map_every, progress, total, save_map
        )
        if len(track) == 0:
            clf.abort()
            outputs.abort()
            folder.discard()
            raise track.stopped if track.stopped is not None else _no_scans(log, start, end)
        finish = functools.partial(
            _finish, folder.path, log, cfg, track, clf, outputs, positioner=positioner,
            labels=_labels(stretch, preset, config_file, found, coverage), out_tum=out_tum,
            relations=relations, plot=plot, map_every=map_every, hash_input=hash_input,
            progress=progress, compile_seconds=compile_seconds,
        )  # fmt: skip
        return _keep(finish, folder, track, clf, outputs)


def _before_the_run(
    cfg: Config,
    given: Path | None,
    out_tum: str | os.PathLike[str] | None,
    bag_out: str | os.PathLike[str] | None,
    compiling: Callable[[], contextlib.AbstractContextManager[object]] | None,
) -> float:
    """Before any output: loop closure's extra (a missing one is a GraphDependencyError), the
    output paths, then the kernels compiled (or loaded; inside ``compiling()`` where their cache
    is cold) before the run's clock starts; returns the seconds that took."""
    if cfg.loop_closure.enabled:
        require_gtsam()
    check_outputs(given, out_tum, bag_out)
    return warm.compile_kernels(cfg, compiling)


def _check_map_every(map_every: object) -> None:
    if isinstance(map_every, bool) or not isinstance(map_every, int) or map_every < 1:
        raise ValueError(f"map_every must be a whole number >= 1, got {map_every!r}")


def _labels(
    stretch: dict[str, Any],
    preset: str | None,
    config_file: str | os.PathLike[str] | None,
    found: list[dict[str, Any]],
    coverage: OdometryCoverage,
) -> dict[str, Any]:
    """What :func:`_finish` puts into ``summary.json`` besides the run's own figures."""
    return {
        "selection": {
            "start_s": stretch["start"],
            "end_s": stretch["end"],
            "max_scans": stretch["max_scans"],
        },
        "config": {"preset": preset, "file": None if config_file is None else str(config_file)},
        "no_return_values_found": found,
        "odometry_coverage": coverage,
    }


def _survey(log: OpenLog, cfg: Config) -> tuple[Config, list[dict[str, Any]], OdometryCoverage]:
    """A first pass over the whole log (:func:`~fuzzypos.io.logs.survey_log`): ``cfg`` with the
    "no return" codes found in its readings that no configured band holds added to
    ``scanner.no_return_bands`` (so the positioner and ``config.toml`` have them), every
    code found (``value_m``, ``readings``, ``invalid_at_range_max``, ``in_configured_band``)
    for ``summary.json``'s ``no_return_values_found``, and which scans the odometry covers
    (``odometry_coverage``; the others are positioned without odometry)."""
    found, coverage = survey_log(log, cfg.scanner)
    return with_found_bands(cfg, found), [f.as_dict() for f in found], coverage


def _open_outputs(
    folder: ResultsFolder,
    source: str,
    bag_out: str | os.PathLike[str] | None,
    storage: str | None,
    frames: OutputFrames | None = None,
) -> tuple[CarmenWriter, _CovarianceOut]:
    """The streamed outputs of a run: ``trajectory.clf``, ``covariance.csv`` and the bag (on
    failure, none, and the folders the run created are removed)."""
    clf: CarmenWriter | None = None
    try:
        clf = CarmenWriter(folder.path / "trajectory.clf", estimate_of=source)
        return clf, _CovarianceOut(folder.path, source, bag_out, storage, frames)
    except BaseException:
        if clf is not None:
            clf.abort()
        folder.discard()
        raise


def _keep(
    finish: Callable[[], RunSummary],
    folder: ResultsFolder,
    track: _Track,
    clf: CarmenWriter,
    outputs: _CovarianceOut,
) -> RunSummary:
    """Write the results (``finish``); raise what stopped the run, if anything did (in the
    loop or after it), with the results kept (:func:`partial_results`)."""
    try:
        summary = finish()
    except BaseException as exc:
        clf.abort()
        outputs.abort()
        if track.stopped is not None:  # what stopped the run, not what failed after it
            raise track.stopped from None
        if is_interrupt(exc):
            raise as_interrupt(exc) from None
        raise
    folder.link_latest()
    if track.stopped is not None:
        track.stopped.__dict__[_PARTIAL] = summary
        raise track.stopped
    return summary
