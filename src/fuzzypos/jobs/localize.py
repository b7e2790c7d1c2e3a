"""The localize job: where the robot is in a saved map, scan by scan (issue 37).

:func:`localize_log` streams a log (:func:`fuzzypos.io.logs.open_log`) through a
``fuzzypos.localization.Localizer`` in an occupancy map (:func:`~fuzzypos.io.occupancy_map.
read_map_yaml`: a ROS map_server map) and writes a results folder as the run job does
(:mod:`fuzzypos.jobs.folders`: by default a new ``results/<log>/<date-time>/``, locked while it
runs, another run's refused unless ``overwrite``). The localizer says, for each scan, whether it
is *searching* (not yet localised), *tracking* (localised: a pose and its covariance in the
map frame) or *lost* (it was tracking and the map no longer fits); only the scans it is
tracking get a pose:

================  ==========================================================================
``trajectory.tum``  the pose in the map frame of every scan the localizer is tracking (none
                    for the others), ``t x y z qx qy qz qw``, ``t`` the scan's stamp
                    (``repr``); a log that never localises gets the header comment only
``covariance.csv``  a header line (:data:`COVARIANCE_COLUMNS`), then one row per pose of
                    ``trajectory.tum``: the stamp, the six entries ``xx xy xθ yy yθ θθ`` of
                    the step's covariance (the increment since the previous scan, in that
                    scan's frame; ``nan`` where the localizer gives none), the same six of the
                    pose's covariance in the map frame (``pose_xx …``), the confidence and the
                    reason, as the run's ``covariance.csv`` lays them out
``config.toml``     the configuration used
``summary.json``    what ran on what (versions, the log's and the map's hashes, the
                    configuration), ``localised``, when (``localised_at``: the scan, its stamp,
                    the seconds since the first scan and the wall-clock seconds from reading
                    the first scan to then), every time it lost and found itself
                    (``events``), the scans per state and per reason, how sure it was
                    (``confidence``: per block of scans, and quantiles over all scans and over
                    the tracked ones), speed, and the errors against the log's truth where it
                    has one (taken to be in the map's frame: a simulated world drawn as the
                    map)
================  ==========================================================================

With ``bag_out`` the poses also go into a bag as they come, as AMCL publishes them:
``geometry_msgs/PoseWithCovarianceStamped`` on ``/amcl_pose`` (the map frame) and the map →
odom transform on ``/tf`` (the pose composed with the inverse of the scan's odometry; none for
a scan without odometry), in the input bag's frames or REP-105's
(:func:`~fuzzypos.jobs.outputs.resolve_bag_frames`).

A job stopped by an error or Ctrl-C after some scans keeps them (``"partial": true`` and why;
:func:`localize_partial`), as a run does.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .._version import __version__
from ..config import Config
from ..errors import Argument, ArgumentError, FuzzyposError, Words
from ..geometry import Pose2D, wrap_angle
from ..io import LogRecord, OdometryBagWriter, OpenLog, open_log, write_text_file, write_tum
from ..io.logs import empty_stretch, select_records, survey_log
from ..io.no_returns import with_found_bands
from ..io.occupancy_map import FREE, OCCUPIED, UNKNOWN, OccupancyMap, read_map_yaml
from ..io.provenance import file_sha256, git_hash, write_json
from ..pipeline import warm
from ..scan import LaserScan
from .folders import ResultsFolder, check_outputs
from .outputs import (
    POSE_COVARIANCE_COLUMNS,
    STEP_COVARIANCE_COLUMNS,
    Steps,
    as_interrupt,
    is_interrupt,
    one_line,
    resolve_bag_frames,
)

__all__ = [
    "AMCL_POSE_TOPIC",
    "COVARIANCE_COLUMNS",
    "InitialPoseOutsideMapError",
    "LocalizeArgumentError",
    "LocalizerMissingError",
    "LocalizeSummary",
    "localize_log",
    "localize_partial",
    "parse_initial_pose",
    "parse_initial_sigma",
]

#: ``covariance.csv``'s columns: the run's step and pose covariances, then the confidence and
#: the reason
COVARIANCE_COLUMNS = (*STEP_COVARIANCE_COLUMNS, *POSE_COVARIANCE_COLUMNS, "confidence", "reason")
#: where ``bag_out`` gets the poses (AMCL's topic)
AMCL_POSE_TOPIC = "/amcl_pose"
#: the localizer's states (``fuzzypos.localization.LocalizerState``'s values)
STATES = ("searching", "tracking", "lost")
#: the localizer the job uses unless given one
_LOCALIZER = ("fuzzypos.localization", "Localizer")
#: where :func:`localize_partial` finds what a stopped job kept
_PARTIAL = "fuzzypos_partial_localization"
_PROGRESS_EVERY = 25
#: ``summary.json``'s confidence blocks: this many scans each, or more to keep at most
#: :data:`_MAX_BLOCKS`
_BLOCK_SCANS, _MAX_BLOCKS = 50, 100

Progress = Callable[[int, "int | None"], None]
Cov6 = tuple[float, float, float, float, float, float]


#: the job's arguments its messages name (:class:`~fuzzypos.errors.Words`)
_POSE, _SIGMA = Argument("initial_pose"), Argument("initial_sigma")


class LocalizeArgumentError(ArgumentError):
    """A bad argument of the localize job (an initial pose or spread that is not one); the
    message names it (``initial_pose``, ``initial_sigma``)."""


class InitialPoseOutsideMapError(LocalizeArgumentError):
    """An initial pose that lies outside the map: the message names the pose and the map's
    extent."""


# -- the localizer, as the job uses it ----------------------------------------------------
class LocalizationEstimateLike(Protocol):
    """What the job reads of ``fuzzypos.localization.LocalizationEstimate``."""

    @property
    def stamp(self) -> float: ...
    @property
    def state(self) -> Any: ...
    @property
    def pose(self) -> Pose2D | Sequence[float] | None: ...
    @property
    def covariance(self) -> Any: ...
    @property
    def step_covariance(self) -> Any: ...
    @property
    def confidence(self) -> float: ...
    @property
    def reason(self) -> str: ...


class LocalizerLike(Protocol):
    """What the job calls of ``fuzzypos.localization.Localizer``."""

    def update(
        self, scan: LaserScan, odom: Pose2D | Sequence[float] | None = None
    ) -> LocalizationEstimateLike: ...


#: ``factory(occupancy_map, config, initial_pose=…, initial_sigma=…)`` → a localizer
LocalizerFactory = Callable[..., LocalizerLike]

if TYPE_CHECKING:  # the real localizer keeps the contract the job is written against
    from ..localization import Localizer

    def _real(occupancy_map: OccupancyMap, config: Config) -> LocalizerLike:
        return Localizer(occupancy_map, config, initial_pose=None, initial_sigma=None)


class LocalizerMissingError(FuzzyposError, OSError):
    """This installation has no localizer (``fuzzypos.localization``)."""

    def __str__(self) -> str:
        return str(self.strerror)


def _default_localizer() -> LocalizerFactory:
    module, name = _LOCALIZER
    try:
        found = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is None or not module.startswith(exc.name):
            raise
        raise LocalizerMissingError(
            errno.ENOENT, f"{module} is not installed: no localizer"
        ) from None
    factory: LocalizerFactory = getattr(found, name)
    return factory


# -- the arguments ---------------------------------------------------------------------------
def _numbers(text: str, what: Argument, n: int, form: str) -> list[float]:
    parts = [p.strip().rstrip("°") for p in str(text).split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise LocalizeArgumentError(Words(what, f" {text!r}: expected {form}"))
    return values


def parse_initial_pose(text: str) -> tuple[float, float, float]:
    """``"x,y,θ"`` (metres, metres, degrees; a ``°`` may follow θ) → ``(x, y, θ)``, θ in
    radians. :class:`LocalizeArgumentError` for anything else."""
    x, y, deg = _numbers(text, _POSE, 3, "three numbers 'x,y,θ' (m, m, degrees)")
    return (x, y, float(wrap_angle(math.radians(deg))))


def parse_initial_sigma(text: str) -> tuple[float, float]:
    """``"m,θ"`` (the initial pose's standard deviations: metres, degrees) → ``(m, rad)``,
    both > 0. :class:`LocalizeArgumentError` for anything else."""
    m, deg = _numbers(text, _SIGMA, 2, "two numbers 'm,θ' (metres, degrees) > 0")
    if m <= 0.0 or deg <= 0.0:
        raise LocalizeArgumentError(Words(_SIGMA, f" {text!r}: both must be > 0"))
    return (m, math.radians(deg))


def _map_extent(m: OccupancyMap) -> str:
    rows, cols = m.shape
    corners = m.cell_centres(np.array([0, 0, rows - 1, rows - 1]), np.array([0, cols - 1] * 2))
    half = 0.5 * m.resolution
    (x0, y0), (x1, y1) = corners.min(axis=0) - half, corners.max(axis=0) + half
    return f"x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m"


def _check_initial_pose(
    m: OccupancyMap, pose: Sequence[float] | None, sigma: tuple[float, float] | None
) -> tuple[float, float, float] | None:
    if pose is None:
        if sigma is not None:
            raise LocalizeArgumentError(Words(_SIGMA, " needs ", _POSE))
        return None
    values = [float(v) for v in pose]
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise LocalizeArgumentError(Words(_POSE, f" must be three finite numbers, got {pose!r}"))
    x, y, theta = values
    if not m.contains(x, y):
        where = "the map" if m.source is None else f"the map {m.source}"
        raise InitialPoseOutsideMapError(
            Words(
                _POSE,
                f" ({x:g} m, {y:g} m, {math.degrees(theta):g}°) lies outside {where} "
                f"({_map_extent(m)})",
            )
        )
    if sigma is not None and not (sigma[0] > 0.0 and sigma[1] > 0.0):
        raise LocalizeArgumentError(Words(_SIGMA, f" must be two numbers > 0, got {sigma!r}"))
    return (x, y, theta)


# -- what the job keeps ----------------------------------------------------------------------
@dataclass(eq=False)
class LocalizeSummary:
    """What :func:`localize_log` did: ``stamps`` and ``poses`` ``(n, 3)`` of the scans it was
    tracking (``trajectory.tum``'s), ``states`` each scan's, ``summary`` ``summary.json``'s
    content, ``files`` name → path of what was written."""

    results_dir: Path
    scans: int
    localised: bool
    stamps: np.ndarray
    poses: np.ndarray
    states: list[str]
    files: dict[str, Path]
    summary: dict[str, Any]
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    localizer_seconds: float = 0.0
    compile_seconds: float = 0.0


def localize_partial(exc: BaseException) -> LocalizeSummary | None:
    """What :func:`localize_log` kept of a job that ``exc`` stopped after some scans, or
    None."""
    kept = exc.__dict__.get(_PARTIAL)
    return kept if isinstance(kept, LocalizeSummary) else None


@dataclass(eq=False)
class _Row:
    """One tracked scan's line of ``trajectory.tum`` and ``covariance.csv``."""

    stamp: float
    pose: tuple[float, float, float]
    step: Cov6 | None
    cov: Cov6
    confidence: float
    reason: str
    truth: tuple[float, float, float] | None


@dataclass(eq=False)
class _Track:
    """What the job keeps of each scan (never the scan), its events and timing."""

    stamps: list[float] = field(default_factory=list)
    states: list[str] = field(default_factory=list)
    confidences: list[float] = field(default_factory=list)
    rows: list[_Row] = field(default_factory=list)
    reasons: dict[str, int] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    localised_at: dict[str, Any] | None = None
    without_odometry: int = 0
    localizer_seconds: float = 0.0
    seconds: float = 0.0
    stopped: BaseException | None = None
    partial_reason: str | None = None

    def __len__(self) -> int:
        return len(self.stamps)


def _state_name(state: object) -> str:
    name = str(getattr(state, "value", state))
    if name not in STATES:
        raise ValueError(f"the localizer's state must be one of {', '.join(STATES)}, got {name!r}")
    return name


def _cov6(c: Any, what: str) -> Cov6:
    a = np.asarray(c, dtype=np.float64)
    if a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be a finite 3x3 array, got {a.shape}")
    c = a.tolist()  # Python floats: their repr in covariance.csv
    return (c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2])


def _pose(p: Pose2D | Sequence[float]) -> tuple[float, float, float]:
    values = tuple(p) if isinstance(p, Pose2D) else tuple(float(v) for v in p)
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"the pose must be three finite numbers, got {p!r}")
    return (float(values[0]), float(values[1]), float(values[2]))


def _row(k: int, rec: LogRecord, est: LocalizationEstimateLike) -> _Row:
    """The tracked scan ``k``'s row (a ``ValueError`` naming it where the estimate lacks its
    pose or covariance)."""
    where = f"scan {k + 1} (stamp {rec.scan.stamp!r}): the localizer is tracking but"
    if est.pose is None or est.covariance is None:
        raise ValueError(f"{where} gives no pose or no covariance")
    try:
        pose, cov = _pose(est.pose), _cov6(est.covariance, "its covariance")
        step = None if est.step_covariance is None else _cov6(est.step_covariance, "its step's")
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where} {exc}") from None
    truth = None if rec.truth is None else _pose(rec.truth)
    return _Row(rec.scan.stamp, pose, step, cov, _confidence(est), str(est.reason), truth)


def _confidence(est: LocalizationEstimateLike) -> float:
    try:
        c = float(est.confidence)
    except (TypeError, ValueError):
        return math.nan
    return c if math.isfinite(c) else math.nan


def _note_state(track: _Track, k: int, stamp: float, state: str, reason: str, t0: float) -> None:
    """The events of scan ``k``'s state: the first time it localises, every time it loses
    itself (tracking → searching or lost) and finds itself again."""
    before = track.states[-1] if track.states else "searching"
    if state == before or (state != "tracking" and before != "tracking"):
        return
    when = {"scan": k + 1, "stamp": stamp, "seconds_since_first_scan": stamp - track.stamps[0]}
    if state == "tracking" and track.localised_at is None:
        track.localised_at = {**when, "wall_seconds": time.perf_counter() - t0}
        track.events.append({"event": "localised", **when, "reason": reason})
    elif state == "tracking":
        track.events.append({"event": "found", **when, "reason": reason})
    else:
        track.events.append({"event": "lost", "state": state, **when, "reason": reason})


def _localize_along(
    records: Iterator[LogRecord],
    localizer: LocalizerLike,
    bag: OdometryBagWriter | None,
    progress: Progress | None,
    total: int | None,
) -> _Track:
    """Run ``localizer`` over ``records``, keeping the :class:`_Track` and streaming the tracked
    poses into ``bag``. An error or Ctrl-C stops the job: kept in ``track.stopped``."""
    track = _Track()
    t_start = time.perf_counter()
    try:
        for k, rec in enumerate(records):
            t0 = time.perf_counter()
            est = localizer.update(rec.scan, rec.odometry)
            track.localizer_seconds += time.perf_counter() - t0
            state = _state_name(est.state)
            row = _row(k, rec, est) if state == "tracking" else None
            track.stamps.append(rec.scan.stamp)
            _note_state(track, k, rec.scan.stamp, state, str(est.reason), t_start)
            track.states.append(state)
            track.confidences.append(_confidence(est))
            track.reasons[str(est.reason)] = track.reasons.get(str(est.reason), 0) + 1
            if row is not None:
                track.rows.append(row)
                track.without_odometry += rec.odometry is None
                if bag is not None:
                    _write_bag(bag, row, rec.odometry)
            if progress is not None and (k + 1) % _PROGRESS_EVERY == 0:
                progress(k + 1, total)
    except (Exception, KeyboardInterrupt) as caught:
        exc = as_interrupt(caught)
        n = len(track)
        if isinstance(exc, KeyboardInterrupt):
            track.partial_reason = f"interrupted at scan {n + 1}"
        else:
            track.partial_reason = f"failed at scan {n + 1}: {one_line(exc)}"
        track.stopped = exc
    track.seconds = time.perf_counter() - t_start
    return track


def _write_bag(bag: OdometryBagWriter, row: _Row, odom: Pose2D | None) -> None:
    xx, xy, xt, yy, yt, tt = row.cov
    cov = np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]])
    bag.write_optimised(row.stamp, row.pose, odom, cov)


# -- after the loop --------------------------------------------------------------------------
def _covariance_text(rows: Iterable[_Row]) -> str:
    lines = [",".join(COVARIANCE_COLUMNS)]
    nan6 = (math.nan,) * 6
    for r in rows:
        numbers = ",".join(map(repr, (float(r.stamp), *(r.step or nan6), *r.cov, r.confidence)))
        reason = r.reason
        if any(ch in reason for ch in ',"\r\n'):
            reason = '"' + reason.replace('"', '""') + '"'
        lines.append(f"{numbers},{reason}")
    return "\n".join(lines) + "\n"


def _quantiles(values: np.ndarray) -> dict[str, float] | None:
    v = values[np.isfinite(values)]
    if v.size == 0:
        return None
    qs = np.quantile(v, [0.05, 0.25, 0.5, 0.75, 0.95])
    return {"p5": qs[0], "p25": qs[1], "p50": qs[2], "p75": qs[3], "p95": qs[4], "mean": v.mean()}


def _confidence_summary(track: _Track) -> dict[str, Any]:
    """How sure the localizer was: per block of scans (its mean, least and greatest confidence
    and the share of the scans it tracked) and quantiles over all and over the tracked."""
    conf = np.array(track.confidences, dtype=np.float64)
    tracking = np.array([s == "tracking" for s in track.states], dtype=bool)
    n = len(conf)
    every = max(_BLOCK_SCANS, math.ceil(n / _MAX_BLOCKS))
    blocks = []
    for a in range(0, n, every):
        c, t = conf[a : a + every], tracking[a : a + every]
        finite = c[np.isfinite(c)]
        blocks.append(
            {
                "first_scan": a + 1,
                "last_scan": a + len(c),
                "mean": float(finite.mean()) if finite.size else None,
                "min": float(finite.min()) if finite.size else None,
                "max": float(finite.max()) if finite.size else None,
                "tracking_share": float(t.mean()),
            }
        )
    return {
        "block_scans": every,
        "blocks": blocks,
        "quantiles": _quantiles(conf),
        "quantiles_tracking": _quantiles(conf[tracking]),
    }


def _truth_errors(rows: list[_Row]) -> dict[str, Any] | None:
    """The tracked poses' errors against the log's truth (taken to be in the map's frame),
    where every tracked scan has one."""
    if not rows or any(r.truth is None for r in rows):
        return None
    est = np.array([r.pose for r in rows])
    truth = np.array([r.truth for r in rows])
    d = np.hypot(est[:, 0] - truth[:, 0], est[:, 1] - truth[:, 1])
    heading = np.abs(wrap_angle(est[:, 2] - truth[:, 2]))
    return {
        "scans": len(rows),
        "mean_position_error_m": float(d.mean()),
        "max_position_error_m": float(d.max()),
        "final_position_error_m": float(d[-1]),
        "mean_heading_error_deg": float(np.degrees(heading).mean()),
        "max_heading_error_deg": float(np.degrees(heading).max()),
    }


def _map_summary(m: OccupancyMap) -> dict[str, Any]:
    yaml = m.source
    return {
        "yaml": None if yaml is None else os.path.abspath(yaml),
        "sha256": None if yaml is None else file_sha256(yaml),
        "resolution_m": m.resolution,
        "origin": {"x": m.origin[0], "y": m.origin[1], "yaw_deg": math.degrees(m.origin[2])},
        "rows": m.shape[0],
        "cols": m.shape[1],
        "cells": {
            "free": int(np.count_nonzero(m.cells == FREE)),
            "occupied": int(np.count_nonzero(m.cells == OCCUPIED)),
            "unknown": int(np.count_nonzero(m.cells == UNKNOWN)),
        },
    }


@dataclass(eq=False)
class _Job:
    """What the job was given, for the files after the loop."""

    log: OpenLog
    occupancy_map: OccupancyMap
    cfg: Config
    labels: dict[str, Any]
    hash_input: bool
    bag: OdometryBagWriter | None
    bag_frames: dict[str, Any] | None
    compile_seconds: float
    #: the bag is finished (never removed after that)
    bag_done: bool = False


def _summary(job: _Job, track: _Track, files: dict[str, Path], notes: list[str]) -> dict[str, Any]:
    """The content of ``summary.json`` (module docstring)."""
    log, n, seconds = job.log, len(track), track.seconds
    states = {s: track.states.count(s) for s in STATES}
    bag = job.bag
    return {
        "fuzzypos_version": __version__,
        "git_hash": git_hash(),
        "input": {
            "path": os.path.abspath(log.name),
            "sha256": file_sha256(log.path) if job.hash_input else None,
            "kind": log.kind,
            "options": log.options,
        },
        "map": _map_summary(job.occupancy_map),
        **job.labels,
        "partial": track.partial_reason is not None,
        "partial_reason": track.partial_reason,
        "localised": track.localised_at is not None,
        "localised_at": track.localised_at,
        "final_state": track.states[-1],
        "scans": n,
        "scans_with_pose": len(track.rows),
        "states": states,
        "reasons": dict(sorted(track.reasons.items(), key=lambda kv: -kv[1])),
        "events": track.events,
        "confidence": _confidence_summary(track),
        "truth_errors": _truth_errors(track.rows),
        "seconds": seconds,
        "scans_per_second": n / seconds if seconds > 0 else None,
        "localizer_seconds": track.localizer_seconds,
        "localizer_ms_per_scan": 1000.0 * track.localizer_seconds / n,
        "compile_seconds": job.compile_seconds,
        "config_values": job.cfg.to_dict(),
        "bad_lines_skipped": log.bad_lines,
        "truncated": log.truncated,
        "first_stamp": track.stamps[0],
        "last_stamp": track.stamps[-1],
        "has_odometry": log.has_odometry,
        "bag_out": None
        if bag is None
        else {
            "path": str(bag.path),
            "storage": bag.storage,
            "frames": job.bag_frames,
            "topics": {bag.pose_topic: bag.optimised_written, "/tf": bag.transforms_written},
        },
        "notes": notes,
        "files": {k: str(v) for k, v in files.items()},
    }


def _finish(out: Path, job: _Job, track: _Track) -> LocalizeSummary:
    """The results folder after the loop, each file a step (:class:`Steps`): one that fails
    or is interrupted makes the job partial and the others are still written;
    ``summary.json`` last."""
    notes = list(dict.fromkeys([*job.log.notes, *getattr(job.log.reader, "notes", [])]))
    steps = Steps(track.stopped, track.partial_reason, notes)
    stamps = np.array([r.stamp for r in track.rows], dtype=np.float64)
    poses = np.array([r.pose for r in track.rows], dtype=np.float64).reshape(-1, 3)
    files: dict[str, Path] = {}

    def tum() -> None:
        what = "part of the" if steps.partial else "the"
        write_tum(
            out / "trajectory.tum",
            stamps,
            poses,
            header_comment=f"fuzzypos {__version__}: {what} poses of {job.log.name} in the map "
            f"{job.occupancy_map.source or ''} where localised (t = the scan's stamp)",
        )

    def bag() -> None:
        assert job.bag is not None
        job.bag.close()
        job.bag_done = True

    for name, write in (
        ("trajectory.tum", tum),
        (
            "covariance.csv",
            lambda: write_text_file(out / "covariance.csv", _covariance_text(track.rows)),
        ),
        ("config.toml", lambda: write_text_file(out / "config.toml", job.cfg.to_toml())),
    ):
        if steps.done(f"while writing {name}", write):
            files[name] = out / name
    if job.bag is not None and steps.done("while writing the bag", bag):
        files["bag"] = job.bag.path
    if job.bag is not None and "bag" not in files:
        job.bag.abort()
    if track.localised_at is None:
        notes.append(f"never localised in {len(track)} scans: no poses were written")
    if track.without_odometry and job.bag is not None:
        notes.append(
            f"{track.without_odometry} localised scans have no odometry: the bag has their "
            "/amcl_pose but no map -> odom transform"
        )
    track.stopped, track.partial_reason = steps.stop, steps.reason
    files["summary.json"] = out / "summary.json"
    summary = _summary(job, track, files, notes)
    if not steps.done(
        "while writing summary.json", lambda: write_json(out / "summary.json", summary)
    ):
        del files["summary.json"]
    track.stopped, track.partial_reason = steps.stop, steps.reason
    return LocalizeSummary(
        results_dir=out,
        scans=len(track),
        localised=track.localised_at is not None,
        stamps=stamps,
        poses=poses,
        states=list(track.states),
        files=files,
        summary=summary,
        notes=notes,
        seconds=track.seconds,
        localizer_seconds=track.localizer_seconds,
        compile_seconds=job.compile_seconds,
    )


# -- the job ---------------------------------------------------------------------------------
def localize_log(
    log: OpenLog | str | os.PathLike[str],
    occupancy_map: OccupancyMap | str | os.PathLike[str],
    config: Config | None = None,
    *,
    initial_pose: Sequence[float] | None = None,
    initial_sigma: tuple[float, float] | None = None,
    results_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    progress: Progress | None = None,
    start: float | None = None,
    end: float | None = None,
    max_scans: int | None = None,
    preset: str | None = None,
    config_file: str | os.PathLike[str] | None = None,
    hash_input: bool = True,
    bag_out: str | os.PathLike[str] | None = None,
    bag_storage: str | None = None,
    bag_frames: Mapping[str, str | None] | None = None,
    localizer: LocalizerFactory | None = None,
    compiling: Callable[[], contextlib.AbstractContextManager[object]] | None = None,
) -> LocalizeSummary:
    """Localise the robot along ``log`` (an :class:`~fuzzypos.io.logs.OpenLog` or a path) in
    ``occupancy_map`` (an :class:`~fuzzypos.io.occupancy_map.OccupancyMap` or a map yaml's
    path) and write a results folder (module docstring): ``trajectory.tum``,
    ``covariance.csv``, ``config.toml``, ``summary.json``; with ``bag_out`` a bag.

    ``initial_pose`` ``(x, y, θ)`` (m, m, rad; in the map frame) and ``initial_sigma`` ``(m,
    rad)`` start the localizer near a pose, as AMCL's ``/initialpose``; without, it searches
    the whole map. ``results_dir``, ``overwrite``, ``start``, ``end``, ``max_scans``,
    ``preset``, ``config_file``, ``hash_input``, ``progress``, ``bag_storage``, ``bag_frames``
    and ``compiling`` as :func:`~fuzzypos.jobs.run.run_log` takes them. ``localizer``: the
    factory ``(occupancy_map, config, initial_pose=, initial_sigma=)`` of the localizer
    (default ``fuzzypos.localization.Localizer``).

    Raises, before anything is written, :class:`~fuzzypos.io.occupancy_map.MapError` /
    ``MapFileError`` (a bad map), :class:`InitialPoseOutsideMapError` and
    :class:`LocalizeArgumentError` (bad arguments), the localizer's own errors (an initial
    pose it refuses), ``ValueError`` (a log without scans in the stretch, a malformed log),
    ``OSError`` (an output path refused). An error or ``KeyboardInterrupt`` after some scans
    is raised once what was done is written (:func:`localize_partial`). A log that never
    localises is no error: ``localised`` is False.
    """
    if not isinstance(log, OpenLog):
        log = open_log(log)
    if not isinstance(occupancy_map, OccupancyMap):
        occupancy_map = read_map_yaml(occupancy_map)
    pose0 = _check_initial_pose(occupancy_map, initial_pose, initial_sigma)
    found, coverage = survey_log(log, (config or Config()).scanner)
    cfg = with_found_bands(config or Config(), found)
    stretch: dict[str, Any] = {"start": start, "end": end, "max_scans": max_scans}
    records = select_records(coverage.records(log.records()), **stretch)
    log.check_stamps(**stretch)
    total = None
    if progress is not None and start is None and end is None:
        hint = log.scan_count_hint()
        total = hint if max_scans is None or hint is None else min(hint, max_scans)
    given = None if results_dir is None else Path(results_dir)
    frames = None if bag_out is None else resolve_bag_frames(log.reader, bag_frames)
    check_outputs(given, None, bag_out)
    compile_seconds = 0.0
    if localizer is None:
        localizer = _default_localizer()
        compile_seconds = warm.compile_kernels(cfg, compiling, in_map=True)
    loc = localizer(occupancy_map, cfg, initial_pose=pose0, initial_sigma=initial_sigma)
    labels = {
        "selection": {"start_s": start, "end_s": end, "max_scans": max_scans},
        "config": {"preset": preset, "file": None if config_file is None else str(config_file)},
        "initial_pose": None
        if pose0 is None
        else {"x": pose0[0], "y": pose0[1], "theta_deg": math.degrees(pose0[2])},
        "initial_sigma": None
        if initial_sigma is None
        else {"m": initial_sigma[0], "deg": math.degrees(initial_sigma[1])},
        "no_return_values_found": [f.as_dict() for f in found],
        "odometry_coverage": coverage.as_dict(),
    }
    folder = ResultsFolder.make(log.name, given, overwrite)
    with folder:
        bag = _open_bag(folder, bag_out, bag_storage, frames)
        job = _Job(log, occupancy_map, cfg, labels, hash_input, bag,
                   None if frames is None else frames.as_dict(), compile_seconds)  # fmt: skip
        track = _localize_along(records, loc, bag, progress, total)
        if len(track) == 0:
            if bag is not None:
                bag.abort()
            folder.discard()
            raise track.stopped if track.stopped is not None else _no_scans(log, start, end)
        return _keep(folder, job, track, progress)


def _open_bag(
    folder: ResultsFolder, bag_out: str | os.PathLike[str] | None, storage: str | None, frames: Any
) -> OdometryBagWriter | None:
    if bag_out is None:
        return None
    try:
        return OdometryBagWriter(
            bag_out, storage, topic=None, frame_id=frames.odom, child_frame_id=frames.base,
            map_frame_id=frames.map, pose_topic=AMCL_POSE_TOPIC,
        )  # fmt: skip
    except BaseException:
        folder.discard()
        raise


def _no_scans(log: OpenLog, start: float | None, end: float | None) -> ValueError:
    if start is not None or end is not None:
        stretch = empty_stretch(log, start, end)
        if stretch is not None:
            return stretch
    return ValueError(f"{log.name}: no scans")


def _keep(
    folder: ResultsFolder, job: _Job, track: _Track, progress: Progress | None
) -> LocalizeSummary:
    """Write the results; raise what stopped the job, if anything did, with them kept."""
    try:
        if progress is not None and track.stopped is None:
            progress(len(track), len(track))
        summary = _finish(folder.path, job, track)
    except BaseException as exc:
        if job.bag is not None and not job.bag_done:
            job.bag.abort()
        if track.stopped is not None:
            raise track.stopped from None
        if is_interrupt(exc):
            raise as_interrupt(exc) from None
        raise
    folder.link_latest()
    if track.stopped is not None:
        track.stopped.__dict__[_PARTIAL] = summary
        raise track.stopped
    return summary
