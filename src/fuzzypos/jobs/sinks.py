"""The run job's outputs (:mod:`fuzzypos.jobs.run`) as sinks of one protocol (:class:`Sink`):
each is opened before the first scan, given every scan's result as it comes
(:meth:`Sink.write`, a :class:`ScanResult`) and closed once after the loop
(:meth:`Sink.close`, ``partial`` where the run stopped early), naming the files it wrote; or
aborted, leaving nothing. They close in the order of the results folder's files:

=====================  ============================================================  =========
sink                   writes                                                        per scan
=====================  ============================================================  =========
:class:`TumSink`       ``trajectory.tum``; ``--out`` (whole runs only)               (track)
:class:`CovarianceSink` ``covariance.csv``                                           a row
:class:`BagSink`       the ``--bag-out`` bag (then loop closure's optimised poses)   a message
:class:`ClfSink`       ``trajectory.clf``, once, at the final poses                  held
:class:`ConfigSink`    ``config.toml``                                               —
:class:`PlotSink`      ``path.png`` (whole runs only)                                map points
:class:`LoopClosureSink` loop closure's files (trajectory_frontend.tum, graph.g2o …)  the graph
:class:`MapSink`       the occupancy map (``--save-map`` without loop closure)       map scans
=====================  ============================================================  =========

The sinks that write at the end read the run's :class:`Track` (stamps, the poses, odometry
and truth of every scan all sinks took; :attr:`Track.final`: the poses after loop closure).
The pose covariance that ``covariance.csv`` and the bag share is carried once per scan
(:class:`PoseCovariances`).
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .._version import __version__
from ..config import Config
from ..geometry import Cov3Upper, Pose2D, covariance_to_parent3, propagate3
from ..graph import LoopClosureResult, OnlineMapper
from ..graph.occupancy import MapScans, map_grid
from ..io import CarmenWriter, LogRecord, OdometryBagWriter, OutputWriteError, write_text_file
from ..io import write_tum as write_tum_file
from ..io._common import _naming
from ..io.bag_info import OutputFrames
from ..pipeline import Estimate
from .outputs import COVARIANCE_COLUMNS

if TYPE_CHECKING:
    from ..io import OpenLog

__all__ = [
    "BagSink",
    "ClfSink",
    "ConfigSink",
    "CovarianceSink",
    "LoopClosureSink",
    "MapSink",
    "PlotSink",
    "PoseCovariances",
    "ScanResult",
    "Sink",
    "Track",
    "TumSink",
]

Row = tuple[float, float, float]


# -- what the sinks share ----------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class StepCovariance:
    """A scan's covariances, checked: the step's ``(3, 3)`` (and as nested floats) and its
    upper triangle, and the pose's upper triangle in the trajectory frame."""

    matrix: np.ndarray
    step: Cov3Upper
    pose: Cov3Upper


@dataclass(frozen=True, slots=True)
class ScanResult:
    """One scan's result, as the sinks are given it: its index in the run (0-based), its
    record (scan, odometry, truth) and the positioner's estimate; ``covariance``: its
    covariances (:class:`PoseCovariances`), None where the estimate has none."""

    index: int
    record: LogRecord
    estimate: Estimate
    covariance: StepCovariance | None


class Sink(Protocol):
    """An output of the run: :meth:`open` before the first scan, :meth:`write` per scan,
    :meth:`close` once after the loop (name → path of the files written), or :meth:`abort`.
    ``what`` names it in a note (``"failed while writing <what>"``); ``whole_runs_only``: a
    partial run does not get it; ``notes``: what it has to say, for ``summary.json``."""

    what: str
    whole_runs_only: bool
    notes: list[str]

    def open(self) -> None: ...

    def write(self, result: ScanResult) -> None: ...

    def close(self, partial: bool) -> dict[str, Path]: ...

    def abort(self) -> None: ...


class _Quiet:
    """A sink's defaults: opens with nothing to do, takes no scans, aborts leaving nothing."""

    what = ""
    whole_runs_only = False

    def __init__(self) -> None:
        self.notes: list[str] = []

    def open(self) -> None:
        pass

    def write(self, result: ScanResult) -> None:
        pass

    def abort(self) -> None:
        pass


def _row(p: Pose2D | None) -> Row | None:
    return None if p is None else (p.x, p.y, p.theta)


def _pose_rows(poses: list[Row | None]) -> np.ndarray | None:
    if not any(p is not None for p in poses):
        return None
    nan = (math.nan, math.nan, math.nan)
    return np.array([p if p is not None else nan for p in poses], dtype=np.float64).reshape(-1, 3)


@dataclass(eq=False)
class Track:
    """What the run keeps of each scan every sink took (never the scan itself), its counts
    and timing; after the loop the arrays (:meth:`freeze`) and :attr:`final`, the poses the
    results carry (loop closure's optimised poses where it finished, else the front end's)."""

    source: str
    stamps: list[float] = field(default_factory=list)
    poses: list[Row] = field(default_factory=list)
    odoms: list[Row | None] = field(default_factory=list)
    truths: list[Row | None] = field(default_factory=list)
    degraded: int = 0
    #: the scans per reason (:class:`~fuzzypos.pipeline.Reason`'s value)
    reasons: dict[str, int] = field(default_factory=dict)
    positioner_seconds: float = 0.0
    seconds: float = 0.0
    compile_seconds: float = 0.0
    #: what stopped the run before the end of the stretch (an error, Ctrl-C), and why
    stopped: BaseException | None = None
    partial_reason: str | None = None
    #: after the loop: the arrays (NaN rows where a scan has no odometry or truth)
    stamp_array: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pose_array: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    odometry: np.ndarray | None = None
    truth: np.ndarray | None = None
    final: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    #: loop closure's result, where its final optimisation finished
    loop: LoopClosureResult | None = None

    def __len__(self) -> int:
        return len(self.stamps)

    def add(self, result: ScanResult) -> None:
        rec, est = result.record, result.estimate
        pose = est.pose
        self.stamps.append(rec.scan.stamp)
        self.poses.append((pose.x, pose.y, pose.theta))
        self.odoms.append(_row(rec.odometry))
        self.truths.append(_row(rec.truth))
        self.degraded += bool(est.degraded)
        why = str(est.reason)
        self.reasons[why] = self.reasons.get(why, 0) + 1

    def freeze(self) -> None:
        """The arrays, the final poses the front end's."""
        self.stamp_array = np.array(self.stamps, dtype=np.float64)
        self.pose_array = np.array(self.poses, dtype=np.float64).reshape(-1, 3)
        self.odometry = _pose_rows(self.odoms)
        self.truth = _pose_rows(self.truths)
        self.final = self.pose_array

    def optimised(self, loop: LoopClosureResult) -> None:
        self.loop, self.final = loop, loop.poses


class PoseCovariances:
    """Each scan's covariances (:class:`StepCovariance`): the step's, checked, and the
    pose's, the steps' propagated from the first scan (the first pose's is the first
    step's) and turned into the trajectory frame, in floats
    (:func:`~fuzzypos.geometry.propagate3`, :func:`~fuzzypos.geometry.covariance_to_parent3`:
    :func:`~fuzzypos.geometry.propagate`'s and :func:`~fuzzypos.geometry.covariance_to_parent`'s
    to rounding, a tenth of their time). A covariance not a finite 3x3 array is a
    ``ValueError`` naming the scan."""

    def __init__(self, source: str) -> None:
        self.source = source
        self._pose: Cov3Upper = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # in the pose's frame

    def of(self, k: int, est: Estimate) -> StepCovariance | None:
        if est.covariance is None:
            return None
        cov = np.asarray(est.covariance, dtype=np.float64)
        c = cov.tolist()  # Python floats: the same repr, without a numpy scalar per entry
        if cov.shape != (3, 3) or not all(math.isfinite(v) for row in c for v in row):
            raise ValueError(
                f"{where(self.source, k, est)}: the covariance must be a finite 3x3 array"
            )
        step = (c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2])
        inc = est.increment
        pose = step if k == 0 else propagate3(self._pose, (inc.x, inc.y, inc.theta), step)
        self._pose = pose
        return StepCovariance(cov, step, covariance_to_parent3(est.pose.theta, pose))


def where(source: str, k: int, est: Estimate) -> str:
    return f"{source}: scan {k + 1} (stamp {est.stamp!r})"


def _no_covariance(source: str, result: ScanResult) -> ValueError:
    what = "the estimate has no covariance (Estimate.covariance)"
    return ValueError(f"{where(source, result.index, result.estimate)}: {what}")


# -- the sinks -------------------------------------------------------------------------------
class TumSink(_Quiet):
    """A trajectory as TUM at the end (the track's stamps, the final poses): the results'
    ``trajectory.tum`` (``key`` ``"trajectory.tum"``; "part of the estimate" in a partial
    run's header) or ``--out`` (``key`` ``"out_tum"``, whole runs only)."""

    def __init__(self, path: Path, key: str, track: Track, *, whole_runs_only: bool) -> None:
        super().__init__()
        self.path, self.key, self.track = path, key, track
        self.whole_runs_only = whole_runs_only
        self.what = key if key == "trajectory.tum" else os.fspath(path)

    def close(self, partial: bool) -> dict[str, Path]:
        t, source = self.track, self.track.source
        if self.key == "trajectory.tum":
            what = "part of the" if partial else "the"
            comment = f"fuzzypos {__version__}: {what} estimate of {source} (t = the scan's stamp)"
        else:
            comment = f"fuzzypos {__version__} estimate of {source}"
        write_tum_file(self.path, t.stamp_array, t.final, header_comment=comment)
        return {self.key: self.path}


class CovarianceSink(_Quiet):
    """``covariance.csv`` (module docstring of :mod:`fuzzypos.jobs.run`), a row per scan,
    written to a temporary name that :meth:`close` renames. A scan without a covariance is a
    ``ValueError`` naming it, but where the first has none and ``required`` is not set (no
    bag wants one): then there is no ``covariance.csv`` (a note says so)."""

    what = "covariance.csv"

    def __init__(self, folder: Path, source: str, *, required: bool) -> None:
        super().__init__()
        self.path, self.source, self.required = folder / "covariance.csv", source, required
        self._tmp = folder / ".covariance.csv.part"
        self._csv: Any = None
        self._reasons: dict[object, str] = {}  # reason → its CSV field
        self.has_covariance = True

    def _reason(self, reason: object) -> str:
        """``reason``'s value as a CSV field (quoted where it has a comma or a quote)."""
        text = self._reasons.get(reason)
        if text is None:
            text = str(reason)
            if any(ch in text for ch in ',"\r\n'):
                text = '"' + text.replace('"', '""') + '"'
            self._reasons[reason] = text
        return text

    def write(self, result: ScanResult) -> None:
        c = result.covariance
        if c is None:
            if result.index == 0 and not self.required:
                self.has_covariance = False
                self.notes.append("no covariance.csv: the positioner gave no covariance")
            if not self.has_covariance:
                return
            raise _no_covariance(self.source, result)
        if self._csv is None:
            with _naming(self.path, self._tmp):
                self._csv = open(self._tmp, "w", encoding="utf-8")  # noqa: SIM115 (closed by close)
                self._csv.write(",".join(COVARIANCE_COLUMNS) + "\n")
        est = result.estimate
        numbers = ",".join(map(repr, (float(est.stamp), *c.step, *c.pose)))
        try:
            self._csv.write(f"{numbers},{self._reason(est.reason)},{1 if est.degraded else 0}\n")
        except OSError as exc:
            raise OutputWriteError(exc.errno, exc.strerror or str(exc), str(self.path)) from exc

    def close(self, partial: bool) -> dict[str, Path]:
        if self._csv is None:
            return {}
        csv, self._csv = self._csv, None
        try:
            with _naming(self.path, self._tmp):
                csv.close()
                os.replace(self._tmp, self.path)
        except BaseException:
            with contextlib.suppress(OSError):
                csv.close()
            self._tmp.unlink(missing_ok=True)
            raise
        return {"covariance.csv": self.path}

    def abort(self) -> None:
        if self._csv is not None:
            csv, self._csv = self._csv, None
            with contextlib.suppress(OSError):
                csv.close()
            self._tmp.unlink(missing_ok=True)


class BagSink(_Quiet):
    """The ``--bag-out`` bag (:class:`~fuzzypos.io.OdometryBagWriter`, module docstring of
    :mod:`fuzzypos.jobs.run`): each scan's pose with the pose covariance in the odom frame,
    the twist over the time since the previous scan (its covariance the step's over dt²;
    zero with unknown covariance at the first scan and where dt <= 0); at :meth:`close`, loop
    closure's optimised poses where it finished. One that cannot be finished is removed:
    noted in a partial run, else raised."""

    what = "the bag"

    def __init__(
        self,
        path: str | os.PathLike[str],
        storage: str | None,
        frames: OutputFrames,
        track: Track,
        source: str,
    ) -> None:
        super().__init__()
        self.path, self.storage, self.frames = path, storage, frames
        self.track, self.source = track, source
        self.bag: OdometryBagWriter | None = None
        self._done = False
        self._stamp = math.nan

    def open(self) -> None:
        f = self.frames
        self.bag = OdometryBagWriter(
            self.path, self.storage, frame_id=f.odom, child_frame_id=f.base, map_frame_id=f.map
        )

    def write(self, result: ScanResult) -> None:
        c, est = result.covariance, result.estimate
        if c is None:
            raise _no_covariance(self.source, result)
        inc = est.increment
        dt = est.stamp - self._stamp
        twist, twist_cov = (0.0, 0.0, 0.0), None
        if result.index > 0 and dt > 0.0:
            twist, twist_cov = (inc.x / dt, inc.y / dt, inc.theta / dt), c.matrix / (dt * dt)
        self._stamp = est.stamp
        xx, xy, xt, yy, yt, tt = c.pose
        world_cov = np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]])
        assert self.bag is not None
        self.bag.write(est.stamp, est.pose, world_cov, twist, twist_cov)

    def close(self, partial: bool) -> dict[str, Path]:
        """Finish the bag: loop closure's optimised poses (with the front end's, and their
        covariances ``(scans, 3, 3)`` in the map frame,
        :func:`~fuzzypos.graph.outputs.optimised_covariances`; None, or a row not finite:
        unknown) appended first (:meth:`~fuzzypos.io.OdometryBagWriter.write_optimised`)."""
        bag, loop = self.bag, self.track.loop
        assert bag is not None
        try:
            if loop is not None:
                stamps, covs = self.track.stamp_array, loop.covariances
                for k, (t, pose, front) in enumerate(
                    zip(stamps, loop.poses, loop.frontend, strict=True)
                ):
                    cov = None if covs is None else covs[k]
                    known = cov is not None and bool(np.all(np.isfinite(cov)))
                    bag.write_optimised(float(t), pose, front, cov if known else None)
            bag.close()
            self._done = True
        except BaseException as exc:
            bag.abort()
            if not partial or not isinstance(exc, Exception):
                raise
            self.notes.append(f"{bag.path}: not kept: {' '.join(str(exc).split())}")
            return {}
        return {"bag": bag.path}

    def abort(self) -> None:
        if self.bag is not None and not self._done:
            self.bag.abort()

    def summary(self) -> dict[str, Any] | None:
        """``summary.json``'s ``bag_out``: the bag, its frames and topics."""
        b = self.bag
        if b is None:
            return None
        topics = {b.pose_topic: b.optimised_written} if b.optimised_written else {}
        return {
            "path": str(b.path),
            "storage": b.storage,
            "frames": self.frames.as_dict(),
            "topics": {b.topic: b.written, "/tf": b.written + b.optimised_written, **topics},
        }


class ClfSink(_Quiet):
    """``trajectory.clf`` (:class:`~fuzzypos.io.CarmenWriter` with ``estimate_of``): streamed
    as the scans come; with loop closure (``held``) their lines wait for the final poses and
    the file is written once at :meth:`close`, at the optimised poses where loop closure
    finished (a header line says so), else at the front end's."""

    what = "trajectory.clf"

    def __init__(self, folder: Path, source: str, track: Track, *, held: bool) -> None:
        super().__init__()
        self.path, self.source, self.track, self.held = (
            folder / "trajectory.clf",
            source,
            track,
            held,
        )
        self.writer: CarmenWriter | None = None

    def open(self) -> None:
        self.writer = CarmenWriter(self.path, estimate_of=self.source, poses_at_close=self.held)

    def write(self, result: ScanResult) -> None:
        rec = result.record
        assert self.writer is not None
        self.writer.write(rec.scan, rec.odometry, rec.truth, pose=result.estimate.pose)

    def close(self, partial: bool) -> dict[str, Path]:
        assert self.writer is not None
        loop = self.track.loop
        why = "x y theta after loop closure: the optimised poses" if loop is not None else ""
        kept = self.writer.close(self.track.final if self.held else None, why)
        self.notes.extend(self.writer.notes)
        return {"trajectory.clf": self.path} if kept else {}

    def abort(self) -> None:
        if self.writer is not None:
            self.writer.abort()


class ConfigSink(_Quiet):
    """``config.toml``: the configuration the run used."""

    what = "config.toml"

    def __init__(self, folder: Path, config: Config) -> None:
        super().__init__()
        self.path, self.config = folder / "config.toml", config

    def close(self, partial: bool) -> dict[str, Path]:
        write_text_file(self.path, self.config.to_toml())
        return {"config.toml": self.path}


class PlotSink(_Quiet):
    """``path.png``: the final path and the odometry over a map of every ``map_every``-th
    scan's points (as the positioner saw them: the configured "no return" bands removed),
    placed by the final poses; whole runs only."""

    what = "path.png"
    whole_runs_only = True

    def __init__(self, folder: Path, log: OpenLog, track: Track, config: Config, map_every: int):
        super().__init__()
        self.path, self.log, self.track, self.map_every = folder / "path.png", log, track, map_every
        self.bands = config.scanner.no_return_bands
        self.points: list[np.ndarray | None] = []

    def write(self, result: ScanResult) -> None:
        k, scan = result.index, result.record.scan
        self.points.append(scan.points_robot(self.bands) if k % self.map_every == 0 else None)

    def close(self, partial: bool) -> dict[str, Path]:
        from ..plot import figures as plotting  # matplotlib only when figures are made
        from .folders import log_name

        t = self.track
        odo_xy = None if t.odometry is None else t.odometry[np.isfinite(t.odometry).all(axis=1)]
        plotting.plot_map(
            t.final,
            self.points[: len(t)],
            odometry=odo_xy,
            path=self.path,
            title=f"{log_name(self.log.name)}: estimated path, odometry and map (scans 1 in "
            f"{self.map_every})",
        )
        return {"path.png": self.path}


class LoopClosureSink(_Quiet):
    """Loop closure online (:class:`~fuzzypos.graph.OnlineMapper`): each scan's estimate into
    the pose graph; after the loop its final optimisation (:meth:`finish`, before the other
    sinks close: they carry its poses) and, at :meth:`close`, its files
    (:meth:`~fuzzypos.graph.LoopClosureResult.write`)."""

    what = "loop closure's files"

    def __init__(self, folder: Path, config: Config, track: Track) -> None:
        super().__init__()
        self.folder, self.config, self.track = folder, config, track
        self.mapper = OnlineMapper(config)

    def write(self, result: ScanResult) -> None:
        self.mapper.add(result.estimate, result.record.scan.angle_increment)

    def finish(self) -> LoopClosureResult:
        return self.mapper.finish()

    def close(self, partial: bool) -> dict[str, Path]:
        loop = self.track.loop
        if loop is None:  # the final optimisation did not finish: no files
            return {}
        return loop.write(
            self.folder,
            self.track.stamp_array,
            self.track.source,
            self.config.loop_closure.map_resolution,
        )


class MapSink(_Quiet):
    """``--save-map`` without loop closure: the occupancy map (``map.pgm``, ``map.yaml``,
    ``map.png``) of the scans kept as they come (:class:`~fuzzypos.graph.occupancy.MapScans`),
    placed by the final poses."""

    what = "the map"

    def __init__(self, folder: Path, config: Config, track: Track) -> None:
        super().__init__()
        lc = config.loop_closure
        self.folder, self.resolution, self.track = folder, lc.map_resolution, track
        self.scans = MapScans(lc.map_scan_distance, lc.map_scan_angle)

    def write(self, result: ScanResult) -> None:
        est = result.estimate
        points = None if est.features is None else est.features.points
        self.scans.add(result.index, est.pose.as_array(), points)

    def close(self, partial: bool) -> dict[str, Path]:
        return map_grid(self.track.final, self.scans.scans, self.resolution).write(self.folder)


#: a sink's close, as the run's steps take it
Closing = Callable[[], dict[str, Path]]
