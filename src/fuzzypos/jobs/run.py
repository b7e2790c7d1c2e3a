"""The run job: running the positioner over a log and keeping the results.

:func:`run_log` streams a log (:func:`fuzzypos.io.logs.open_log`) through a
:class:`~fuzzypos.pipeline.Positioner` and writes a results folder, which holds one run: by
default a new ``results/<log>/<date-time>/`` (:func:`default_results_dir`; ``<log>`` is
:func:`log_name` with ``keep_format``: the file name without a compression suffix) with
``results/<log>/latest`` linked to it; a folder given that holds another run's results is
refused, or with ``overwrite=True`` cleared first (:class:`ResultsFolderError`); the run locks
it until it ends. A run stopped by an error or Ctrl-C after some scans keeps them: the files
below (but ``path.png``) for the scans done, ``summary.json`` saying ``"partial": true`` and
why (:class:`PartialRunError`); so does one stopped after its loop (loop closure's final
optimisation: the front end's poses are written; a writer: the other files are), each step
after the loop a :class:`~fuzzypos.jobs.outputs.Steps` step.

One :class:`RunJob` runs it over the outputs as sinks of one protocol
(:mod:`fuzzypos.jobs.sinks`: open, write each scan's result, close once, partial or not);
its :class:`RunSummary` is ``summary.json`` typed (:meth:`RunSummary.to_json`).

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
                    codes found in the log's readings (:func:`~fuzzypos.io.logs.survey_log`)
================  ==========================================================================

With ``bag_out=`` the estimate also goes into a bag as it runs
(:class:`~fuzzypos.jobs.sinks.BagSink`, :class:`~fuzzypos.io.OdometryBagWriter`):
``nav_msgs/Odometry`` on ``/fuzzypos/odom`` and ``/tf`` (odom → base), in REP-105 frames
(``bag_frames``, else the input bag's, else ``base_link``, ``odom``, ``map``;
``summary.json``'s ``bag_out``). The pose's covariance is the increments' propagated from
the first scan (:func:`~fuzzypos.geometry.propagate`; the first pose's covariance is the
first estimate's), turned into the odom frame
(:func:`~fuzzypos.geometry.covariance_to_parent`); the twist is the increment over the time
since the previous scan (its covariance the increment's over dt²), zero with unknown
covariance at the first scan and where dt <= 0. With loop closure the optimised poses follow
on ``/fuzzypos/pose`` (map frame, their covariance the pose graph's marginals carried to
each scan and rotated into the map frame, as in ``covariance_optimised.csv``:
:func:`~fuzzypos.graph.outputs.optimised_covariances`) with map → odom on ``/tf``.

Memory stays small on long logs: only the stamps and poses (estimate, odometry, truth)
and the points of every ``map_every``-th scan are kept, never the scans; with loop closure
``trajectory.clf``'s lines wait as text for the optimised poses, so that it is written once.

The log is read twice: a survey of the whole log first (:func:`~fuzzypos.io.logs.survey_log`:
the "no return" codes its readings use, which the positioner must know from the first scan,
and which scans the odometry covers), which also takes every scan's stamp for the stamps'
check and the progress total, then the run itself.
"""

from __future__ import annotations

import contextlib
import functools
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from ..config import Config
from ..errors import FuzzyposError
from ..eval.metrics import (
    EvaluationError,
    TrajectoryErrors,
    relations_errors,
    trajectory_errors,
)
from ..geometry import Pose2D
from ..graph import require_gtsam
from ..io import CarmenWriter, LogRecord, OpenLog, Relations, open_log
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
)
from .outputs import (
    COVARIANCE_COLUMNS,
    POSE_COVARIANCE_COLUMNS,
    STEP_COVARIANCE_COLUMNS,
    Steps,
    as_interrupt,
    is_interrupt,
    one_line,
    resolve_bag_frames,
)
from .sinks import (
    BagSink,
    ClfSink,
    ConfigSink,
    CovarianceSink,
    LoopClosureSink,
    MapSink,
    PlotSink,
    PoseCovariances,
    ScanResult,
    Sink,
    Track,
    TumSink,
)

__all__ = [
    "COVARIANCE_COLUMNS",
    "POSE_COVARIANCE_COLUMNS",
    "RESULT_FILES",
    "STEP_COVARIANCE_COLUMNS",
    "PartialRunError",
    "Progress",
    "ResultsFolderError",
    "RunJob",
    "RunSummary",
    "TruthErrors",
    "as_interrupt",
    "default_results_dir",
    "is_interrupt",
    "partial_results",
    "run_log",
    "write_estimate_clf",
]

#: ``progress(done, total)`` (``total`` None when unknown)
Progress = Callable[[int, "int | None"], None]

#: how often (in scans) :func:`run_log` reports its progress
_PROGRESS_EVERY = 25


# -- what a run did --------------------------------------------------------------------------
@dataclass(frozen=True)
class TruthErrors:
    """``summary.json``'s ``truth_errors``: the estimate's errors against the log's truth
    (``TRUEPOS``, where every scan has one), and the odometry's where it covers every scan."""

    estimate: TrajectoryErrors
    odometry: TrajectoryErrors | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"estimate": self.estimate.as_dict()}
        if self.odometry is not None:
            out["odometry"] = self.odometry.as_dict()
        return out


@dataclass(eq=False)
class RunSummary:
    """What :func:`run_log` did: ``summary.json`` typed (:meth:`to_json` gives it, key for
    key, as :func:`run_log` describes it), with the run's arrays and where its results are.

    ``stamps`` ``(n,)``, ``poses`` ``(n, 3)`` (the estimate), ``odometry`` ``(n, 3)`` or None
    (NaN rows for scans without odometry), ``truth`` likewise; ``files``: name → path of
    what was written; with loop closure ``online_poses`` (each scan's pose as first output
    online) and ``frontend_poses``. The sections of ``summary.json`` that are tables of their
    own (``input``, ``selection``, ``reasons``, ``truth_errors``, ``relations``,
    ``loop_closure`` …) are its dicts.
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
    notes: list[str] = field(default_factory=list)
    online_poses: np.ndarray | None = None
    frontend_poses: np.ndarray | None = None
    #: the kernels' compiling (or loading) before the first scan, not in the figures above
    compile_seconds: float = 0.0
    partial_reason: str | None = None
    fuzzypos_version: str = __version__
    git_hash: str | None = None
    input: dict[str, Any] = field(default_factory=dict)
    selection: dict[str, Any] = field(default_factory=dict)
    reasons: dict[str, int] = field(default_factory=dict)
    odometry_noise: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    bad_lines_skipped: int = 0
    truncated: bool = False
    scan_rate_hz: float | None = None
    truth_errors: TruthErrors | None = None
    relations: dict[str, Any] | None = None
    no_return_values_found: list[dict[str, Any]] = field(default_factory=list)
    bag_out: dict[str, Any] | None = None
    odometry_coverage: dict[str, Any] = field(default_factory=dict)
    loop_closure: dict[str, Any] | None = None
    #: the files as ``summary.json`` names them (the file itself among them)
    listed_files: dict[str, str] = field(default_factory=dict)

    @property
    def partial(self) -> bool:
        return self.partial_reason is not None

    @property
    def scans_per_second(self) -> float:
        return self.scans / self.seconds if self.seconds > 0 else float("nan")

    @property
    def positioner_ms_per_scan(self) -> float:
        return 1000.0 * self.positioner_seconds / self.scans

    def to_json(self) -> dict[str, Any]:
        """The content of ``summary.json``, in its order."""
        n, seconds = self.scans, self.seconds
        out: dict[str, Any] = {
            "fuzzypos_version": self.fuzzypos_version,
            "git_hash": self.git_hash,
            "input": self.input,
            "selection": self.selection,
            "partial": self.partial,
            "partial_reason": self.partial_reason,
            "scans": n,
            "scans_degraded": self.scans_degraded,
            "reasons": self.reasons,
            "odometry_noise": self.odometry_noise,
            "odometry_jumps_rejected": self.odometry_jumps_rejected,
            "seconds": seconds,
            "scans_per_second": n / seconds if seconds > 0 else None,
            "positioner_seconds": self.positioner_seconds,
            "positioner_ms_per_scan": self.positioner_ms_per_scan,
            "compile_seconds": self.compile_seconds,
            "config": self.config,
            "bad_lines_skipped": self.bad_lines_skipped,
            "truncated": self.truncated,
            "scan_rate_hz": self.scan_rate_hz,
            "first_stamp": float(self.stamps[0]),
            "last_stamp": float(self.stamps[-1]),
            "has_odometry": self.odometry is not None,
            "has_truth": self.truth is not None,
            "truth_errors": None if self.truth_errors is None else self.truth_errors.as_dict(),
            "relations": self.relations,
            "notes": self.notes,
            "files": self.listed_files,
            "no_return_values_found": self.no_return_values_found,
            "bag_out": self.bag_out,
            "odometry_coverage": self.odometry_coverage,
        }
        if self.loop_closure is not None:
            out["loop_closure"] = self.loop_closure
        return out

    @property
    def summary(self) -> dict[str, Any]:
        """:meth:`to_json` (the name of earlier releases)."""
        return self.to_json()


class PartialRunError(FuzzyposError, ValueError):
    """A run stopped after some scans by an error (:attr:`stopped`, also its ``__cause__``;
    the message is its), with what was kept: :attr:`summary`, its results folder's
    ``summary.json`` saying ``"partial": true``. A run stopped by Ctrl-C raises the
    ``KeyboardInterrupt`` with this as its ``__cause__`` (:func:`partial_results`)."""

    def __init__(self, summary: RunSummary, stopped: BaseException) -> None:
        super().__init__(one_line(stopped))
        self.summary = summary
        self.stopped = stopped

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.summary, self.stopped))


class _PartialRunOSError(PartialRunError, OSError):
    """A :class:`PartialRunError` that a file-system error stopped (an ``OSError`` too)."""


def _partial(summary: RunSummary, stopped: BaseException) -> BaseException:
    """What :func:`run_log` raises for a run ``stopped`` after some scans: a
    :class:`PartialRunError` for an error it reports (``ValueError``, ``OSError``), else (Ctrl-C,
    a bug) ``stopped`` itself, the :class:`PartialRunError` its ``__cause__``."""
    error = (_PartialRunOSError if isinstance(stopped, OSError) else PartialRunError)(
        summary, stopped
    )
    if isinstance(stopped, (ValueError, OSError)):
        error.__cause__ = stopped
        return error
    stopped.__cause__ = error
    return stopped


def partial_results(exc: BaseException) -> RunSummary | None:
    """What :func:`run_log` kept of a run that ``exc`` stopped after some scans (its results
    folder, ``summary.json`` marked partial): a :class:`PartialRunError`'s summary, or that of
    the one behind a ``KeyboardInterrupt``; None for any other exception."""
    if isinstance(exc, PartialRunError):
        return exc.summary
    cause = exc.__cause__
    return cause.summary if isinstance(cause, PartialRunError) else None


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
class RunJob:
    """One run of a positioner over a log's records into a results folder, through its
    outputs as sinks (:mod:`fuzzypos.jobs.sinks`): :meth:`open` them, :meth:`position` along
    the records (each scan's result to every sink, then into the :class:`Track`), then
    :meth:`finish` (loop closure's final optimisation, every sink closed in the order of the
    results folder's files, the scores, ``summary.json`` last). A sink's failure after the loop
    is a step (:class:`~fuzzypos.jobs.outputs.Steps`): the run is partial, the others still
    close."""

    def __init__(
        self,
        log: OpenLog,
        config: Config,
        folder: ResultsFolder,
        *,
        out_tum: str | os.PathLike[str] | None = None,
        bag_out: str | os.PathLike[str] | None = None,
        bag_storage: str | None = None,
        frames: OutputFrames | None = None,
        plot: bool = True,
        map_every: int = 10,
        save_map: bool = False,
    ) -> None:
        self.log, self.config, self.folder = log, config, folder
        self.positioner = Positioner(config)
        self.track = Track(log.name)
        self.covariances = PoseCovariances(log.name)
        out, name, t = folder.path, log.name, self.track
        lc = config.loop_closure.enabled
        csv = CovarianceSink(out, name, required=bag_out is not None)
        self.bag = None
        if bag_out is not None:
            self.bag = BagSink(bag_out, bag_storage, frames or OutputFrames(), t, name)
        extra = (
            None if out_tum is None else TumSink(Path(out_tum), "out_tum", t, whole_runs_only=True)
        )
        clf = ClfSink(out, name, t, held=lc)
        picture = PlotSink(out, log, t, config, map_every) if plot else None
        self.loop = LoopClosureSink(out, config, t) if lc else None
        grid = MapSink(out, config, t) if save_map and not lc else None
        tum = TumSink(out / "trajectory.tum", "trajectory.tum", t, whole_runs_only=False)
        closing = (
            tum,
            csv,
            self.bag,
            extra,
            clf,
            ConfigSink(out, config),
            picture,
            self.loop,
            grid,
        )
        #: the sinks in the order they close (the results folder's files' order)
        self.sinks: list[Sink] = [s for s in closing if s is not None]
        #: and in the order each scan reaches them
        self.writers: list[Sink] = [
            s for s in (csv, self.bag, self.loop, grid, clf, picture) if s is not None
        ]

    def open(self) -> None:
        """Open every sink; on a failure, none stays open and the folder is removed."""
        opened: list[Sink] = []
        try:
            for sink in self.sinks:
                sink.open()
                opened.append(sink)
        except BaseException:
            self.abort(opened)
            self.folder.discard()
            raise

    def abort(self, sinks: Iterable[Sink] | None = None) -> None:
        for sink in self.sinks if sinks is None else sinks:
            sink.abort()

    def run(
        self,
        records: Iterator[LogRecord],
        progress: Progress | None,
        total: int | None,
        compile_seconds: float = 0.0,
    ) -> Track:
        """:meth:`open`, :meth:`position`; where no scan was positioned, the sinks aborted and
        the folder removed (nothing kept)."""
        self.open()
        track = self.position(records, progress, total)
        track.compile_seconds = compile_seconds
        if len(track) == 0:
            self.abort()
            self.folder.discard()
        return track

    def position(
        self, records: Iterator[LogRecord], progress: Progress | None, total: int | None
    ) -> Track:
        """Run the positioner over ``records``, each scan's result to every sink and then into
        the track. An error or Ctrl-C stops the run: it is kept in ``track.stopped`` (anything
        else aborts the sinks and is raised)."""
        track, positioner, writers = self.track, self.positioner, self.writers
        t_start = time.perf_counter()
        try:
            for k, rec in enumerate(records):
                t0 = time.perf_counter()
                est = positioner.update(rec.scan, rec.odometry)
                track.positioner_seconds += time.perf_counter() - t0
                result = ScanResult(k, rec, est, self.covariances.of(k, est))
                for sink in writers:
                    sink.write(result)
                track.add(result)
                if progress is not None and (k + 1) % _PROGRESS_EVERY == 0:
                    progress(k + 1, total)
        except (Exception, KeyboardInterrupt) as exc:
            stopped = as_interrupt(exc)  # numba's SystemError around Ctrl-C: Ctrl-C
            track.stopped = stopped
            at = f"scan {len(track) + 1}"
            interrupted = isinstance(stopped, KeyboardInterrupt)
            track.partial_reason = (
                f"interrupted at {at}" if interrupted else f"failed at {at}: {one_line(stopped)}"
            )
        except BaseException:
            self.abort()
            raise
        track.seconds = time.perf_counter() - t_start
        return track

    def finish(
        self,
        *,
        labels: dict[str, Any],
        relations: Relations | None,
        hash_input: bool,
        progress: Progress | None,
    ) -> RunSummary:
        """After the loop: loop closure's final optimisation, the sinks closed (``summary.json``
        last), the run summed up. Each is a step (:class:`Steps`): one that fails or is
        interrupted makes the run partial (``track.stopped``, ``partial_reason``) and the rest
        is still done; where loop closure did not finish, its files are not written and
        ``trajectory.tum`` and ``trajectory.clf`` hold the front end's poses."""
        log, track = self.log, self.track
        notes = list(dict.fromkeys([*log.notes, *getattr(log.reader, "notes", [])]))
        steps = Steps(track.stopped, track.partial_reason, notes)
        n = len(track)
        if progress is not None and not steps.partial:
            steps.run("after the last scan", lambda: progress(n, n))
        track.freeze()
        self._final_optimisation(steps)
        files = self._close_sinks(steps)
        out = self.folder.path
        summary = self._scored(steps, labels, relations, hash_input)
        track.stopped, track.partial_reason = steps.stop, steps.reason
        files["summary.json"] = out / "summary.json"
        summary.partial_reason = track.partial_reason
        summary.files, summary.listed_files = files, {k: str(v) for k, v in files.items()}
        coverage = labels["odometry_coverage"]
        note = coverage.note()
        if note is not None and note not in notes:
            notes.append(note)
        if not steps.done(
            "while writing summary.json",
            lambda: write_json(out / "summary.json", summary.to_json()),
        ):
            del files["summary.json"]
        track.stopped, track.partial_reason = steps.stop, steps.reason
        return summary

    def _final_optimisation(self, steps: Steps) -> None:
        """Loop closure's final optimisation (a step), its poses the track's final ones; the
        front end's where it did not finish, or the run is partial."""
        if self.loop is None or steps.partial:
            return
        loop = steps.run("in loop closure's final optimisation", self.loop.finish)
        if loop is None:
            steps.notes.append(
                "loop closure did not finish: trajectory.tum holds the front end's poses"
            )
            return
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
        self.track.optimised(loop)

    def _close_sinks(self, steps: Steps) -> dict[str, Path]:
        """Close every sink, each a step (but those for whole runs only, in a partial run);
        name → path of the files written, in writing order."""
        files: dict[str, Path] = {}
        for sink in self.sinks:
            if not (sink.whole_runs_only and steps.partial):
                close = functools.partial(sink.close, steps.partial)
                files.update(steps.run(f"while writing {sink.what}", close) or {})
        for sink in self.sinks:
            steps.notes.extend(sink.notes)
        if steps.partial:
            missing = [] if "path.png" in files else ["no path.png"]
            extra = [s for s in self.sinks if isinstance(s, TumSink) and s.key == "out_tum"]
            if extra and "out_tum" not in files:
                missing.append(f"{extra[0].path} was not written")
            steps.notes.append("a partial run" + (": " + ", and ".join(missing) if missing else ""))
        return files

    def _scored(
        self,
        steps: Steps,
        labels: dict[str, Any],
        relations: Relations | None,
        hash_input: bool,
    ) -> RunSummary:
        """The run summed up: the scores against the truth and the relations (steps), and
        what it ran on."""
        log, t, loop = self.log, self.track, self.track.loop
        truth_errors = steps.run(
            "scoring against the truth",
            lambda: _truth_errors(t.truth, t.final, t.odometry, t.degraded),
        )
        rel = steps.run(
            "while scoring against the relations",
            lambda: _relations_errors(t.stamp_array, t.final, relations, steps.notes),
        )
        loop_rel = {}
        if loop is not None and relations is not None and loop.online is not None:
            for name, poses in (("frontend", loop.frontend), ("online", loop.online)):
                loop_rel[f"relations_{name}"] = steps.run(
                    "while scoring against the relations",
                    functools.partial(
                        _relations_errors, t.stamp_array, poses, relations, steps.notes
                    ),
                )
        return RunSummary(
            results_dir=self.folder.path,
            scans=len(t),
            scans_degraded=t.degraded,
            odometry_jumps_rejected=int(self.positioner.odometry_jumps),
            seconds=t.seconds,
            positioner_seconds=t.positioner_seconds,
            compile_seconds=t.compile_seconds,
            stamps=t.stamp_array,
            poses=t.final,
            odometry=t.odometry,
            truth=t.truth,
            files={},
            notes=steps.notes,
            online_poses=None if loop is None else loop.online,
            frontend_poses=None if loop is None else loop.frontend,
            partial_reason=steps.reason,
            git_hash=git_hash(),
            input={
                "path": os.path.abspath(log.name),
                "sha256": file_sha256(log.path) if hash_input else None,
                "kind": log.kind,
                "options": log.options,
            },
            selection=labels["selection"],
            reasons=_reason_counts(t.reasons),
            odometry_noise=self.positioner.odometry_noise.as_dict(),
            config=labels["config"],
            bad_lines_skipped=log.bad_lines,
            truncated=log.truncated,
            scan_rate_hz=log.scan_rate_hz,
            truth_errors=truth_errors,
            relations=rel,
            no_return_values_found=labels["no_return_values_found"],
            bag_out=None if self.bag is None else self.bag.summary(),
            odometry_coverage=labels["odometry_coverage"].as_dict(),
            loop_closure=None if loop is None else {**loop.summary, **loop_rel},
        )


def _truth_errors(
    truth: np.ndarray | None, poses: np.ndarray, odometry: np.ndarray | None, degraded: int
) -> TruthErrors | None:
    """The estimate's (and the odometry's) errors against the log's truth, where every scan
    has one."""
    if truth is None or not np.isfinite(truth).all():
        return None
    odo = None
    if odometry is not None and np.isfinite(odometry).all():
        odo = trajectory_errors(truth, odometry, 0)
    return TruthErrors(trajectory_errors(truth, poses, degraded), odo)


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


def _reason_counts(counts: dict[str, int]) -> dict[str, int]:
    """The scans per reason, in :class:`~fuzzypos.pipeline.Reason`'s order (any other after)."""
    order = [r.value for r in Reason if r.value in counts]
    return {why: counts[why] for why in [*order, *(w for w in counts if w not in order)]}


def _no_scans(log: OpenLog, start: float | None, end: float | None) -> ValueError:
    if start is not None or end is not None:
        stretch = empty_stretch(log, start, end)
        if stretch is not None:  # the log has scans, but not there
            return stretch
    hint = " (is it a CARMEN log with FLASER or ROBOTLASER1 lines?)" if log.kind == "carmen" else ""
    return ValueError(f"{log.name}: no scans{hint}")


def _scans_in_stretch(
    log: OpenLog, start: float | None, end: float | None, max_scans: int | None
) -> int | None:
    """The scans of the stretch, for the progress bar: the whole log's count, or with
    ``start``/``end`` those its scans' stamps put in the stretch
    (:meth:`~fuzzypos.io.logs.OpenLog.scan_stamps`, which the survey took); None when
    unknown."""
    total: int | None = None
    if start is None and end is None:
        total = log.scan_count_hint()
    else:
        with contextlib.suppress(OSError):
            total = len(select_stamps(log.scan_stamps(), start=start, end=end))
    if max_scans is not None:
        total = max_scans if total is None else min(total, max_scans)
    return total


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

    ``summary.json`` (:meth:`RunSummary.to_json`) holds: ``fuzzypos_version``, ``git_hash``
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
    :class:`~fuzzypos.jobs.folders.ResultsFolderBusyError`). An error after some scans is
    raised, once what was done is written (``"partial": true``, ``"partial_reason"``:
    ``"failed at scan N: …"``, ``"failed while writing F: No space left on device"`` …; no
    ``path.png`` or ``out_tum`` after it), as a :class:`PartialRunError` carrying the
    :class:`RunSummary` (an ``OSError`` too where one stopped the run); Ctrl-C (numba's
    ``SystemError`` around one too) as the ``KeyboardInterrupt``, the
    :class:`PartialRunError` its ``__cause__`` (``"interrupted at scan N"``, ``"interrupted
    in loop closure's final optimisation"`` …; :func:`partial_results`). Before the first
    scan, nothing is kept.
    """
    if not isinstance(log, OpenLog):
        log = open_log(log)
    cfg, found, coverage = _survey(log, config if config is not None else Config())
    _check_map_every(map_every)
    stretch: dict[str, Any] = {"start": start, "end": end, "max_scans": max_scans}
    records = select_records(coverage.records(log.records()), **stretch)
    log.check_stamps(**stretch)  # corrupt stamps: StampError
    total = _scans_in_stretch(log, start, end, max_scans) if progress is not None else None
    given = None if results_dir is None else Path(results_dir)
    frames = None if bag_out is None else resolve_bag_frames(log.reader, bag_frames)
    compile_seconds = _before_the_run(cfg, given, out_tum, bag_out, compiling)
    folder = ResultsFolder.make(log.name, given, overwrite)
    with folder:  # locked by this run until it ends
        job = RunJob(
            log, cfg, folder, out_tum=out_tum, bag_out=bag_out, bag_storage=bag_storage,
            frames=frames, plot=plot, map_every=map_every, save_map=save_map,
        )  # fmt: skip
        track = job.run(records, progress, total, compile_seconds)
        if len(track) == 0:
            raise track.stopped if track.stopped is not None else _no_scans(log, start, end)
        finish = functools.partial(
            job.finish, labels=_labels(stretch, preset, config_file, found, coverage),
            relations=relations, hash_input=hash_input, progress=progress,
        )  # fmt: skip
        return _keep(finish, job)


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
    """What :meth:`RunJob.finish` puts into ``summary.json`` besides the run's own figures."""
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
    (``odometry_coverage``; the others are positioned without odometry). It also takes the
    scans' stamps (:meth:`~fuzzypos.io.logs.OpenLog.scan_stamps`), so that the stamps' check
    and the progress total read the log no more."""
    found, coverage = survey_log(log, cfg.scanner)
    return with_found_bands(cfg, found), [f.as_dict() for f in found], coverage


def _keep(finish: Callable[[], RunSummary], job: RunJob) -> RunSummary:
    """Write the results (``finish``); raise what stopped the run, if anything did (in the
    loop or after it), with the results kept (:class:`PartialRunError`)."""
    track = job.track
    try:
        summary = finish()
    except BaseException as exc:
        job.abort()
        if track.stopped is not None:  # what stopped the run, not what failed after it
            raise track.stopped from None
        if is_interrupt(exc):
            raise as_interrupt(exc) from None
        raise
    job.folder.link_latest()
    if track.stopped is not None:
        raise _partial(summary, track.stopped)
    return summary
