"""The run job's streamed outputs (:mod:`fuzzypos.jobs.run`): ``covariance.csv`` and the bag,
written scan by scan (:class:`_CovarianceOut`; its frames: :func:`resolve_bag_frames`; loop
closure's optimised poses appended at its end), and the steps after the loop
(:class:`Steps`): each one that fails or is interrupted is noted and makes the run partial,
and the others still run, so that what was done is kept."""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ..geometry import Cov3Upper, covariance_to_parent3, propagate3
from ..io import BagReader, OdometryBagWriter, OutputWriteError
from ..io._common import _naming
from ..io.bag_info import OutputFrames, output_frames, read_tf_pairs
from ..pipeline import Estimate

__all__ = [
    "COVARIANCE_COLUMNS",
    "POSE_COVARIANCE_COLUMNS",
    "STEP_COVARIANCE_COLUMNS",
    "Steps",
    "as_interrupt",
    "resolve_bag_frames",
    "is_interrupt",
]

T = TypeVar("T")

#: ``covariance.csv``'s first columns, as they always were: the stamp, then the step's (the
#: increment's) covariance's upper triangle
STEP_COVARIANCE_COLUMNS = ("stamp", "xx", "xy", "xtheta", "yy", "ytheta", "thetatheta")
#: then the pose's covariance in the trajectory frame, likewise
POSE_COVARIANCE_COLUMNS = tuple(f"pose_{c}" for c in STEP_COVARIANCE_COLUMNS[1:])
#: ``covariance.csv``'s columns (module docstring)
COVARIANCE_COLUMNS = (*STEP_COVARIANCE_COLUMNS, *POSE_COVARIANCE_COLUMNS, "reason", "degraded")


class _CovarianceOut:
    """``covariance.csv`` (written to a temporary name, renamed by :meth:`close`) and, with
    ``bag_out``, the bag, streamed scan by scan (module docstring). The pose's covariance is
    carried in floats (:func:`~fuzzypos.geometry.propagate3`,
    :func:`~fuzzypos.geometry.covariance_to_parent3`: :func:`~fuzzypos.geometry.propagate`'s
    and :func:`~fuzzypos.geometry.covariance_to_parent`'s to rounding, a tenth of their time).
    A scan without a covariance is a ``ValueError`` naming it, but where the first has none
    and no bag is asked for: then there is no ``covariance.csv`` (a note says so)."""

    def __init__(
        self,
        out: Path,
        source: str,
        bag_out: str | os.PathLike[str] | None,
        storage: str | None,
        frames: OutputFrames | None = None,
    ) -> None:
        self.path, self.source = out / "covariance.csv", source
        self._tmp = out / ".covariance.csv.part"
        self._csv: Any = None
        self._reasons: dict[object, str] = {}  # reason → its CSV field
        self.has_covariance = True
        self.notes: list[str] = []
        self.frames = OutputFrames() if frames is None else frames
        self.bag = None
        if bag_out is not None:
            f = self.frames
            self.bag = OdometryBagWriter(
                bag_out, storage, frame_id=f.odom, child_frame_id=f.base, map_frame_id=f.map
            )
        self._bag_done = False
        self._pose_cov: Cov3Upper = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # in the pose's frame
        self._stamp = math.nan

    def _covariance(self, k: int, est: Estimate) -> tuple[np.ndarray, list[list[float]]] | None:
        """The estimate's covariance, checked, and as floats; None where the run has none."""
        if est.covariance is None:
            if k == 0 and self.bag is None:
                self.has_covariance = False
                self.notes.append("no covariance.csv: the positioner gave no covariance")
            if not self.has_covariance:
                return None
            what = "the estimate has no covariance (Estimate.covariance)"
            raise ValueError(f"{self._where(k, est)}: {what}")
        cov = np.asarray(est.covariance, dtype=np.float64)
        c = cov.tolist()  # Python floats: the same repr, without a numpy scalar per entry
        if cov.shape != (3, 3) or not all(math.isfinite(v) for row in c for v in row):
            raise ValueError(f"{self._where(k, est)}: the covariance must be a finite 3x3 array")
        return cov, c

    def _where(self, k: int, est: Estimate) -> str:
        return f"{self.source}: scan {k + 1} (stamp {est.stamp!r})"

    def _reason(self, reason: object) -> str:
        """``reason``'s value as a CSV field (quoted where it has a comma or a quote)."""
        field = self._reasons.get(reason)
        if field is None:
            text = str(reason)
            quote = any(ch in text for ch in ',"\r\n')
            field = '"' + text.replace('"', '""') + '"' if quote else text
            self._reasons[reason] = field
        return field

    def write(self, k: int, est: Estimate) -> None:
        checked = self._covariance(k, est)
        if checked is None:
            return
        cov, c = checked
        if self._csv is None:
            with _naming(self.path, self._tmp):
                self._csv = open(self._tmp, "w", encoding="utf-8")  # noqa: SIM115 (closed by close)
                self._csv.write(",".join(COVARIANCE_COLUMNS) + "\n")
        step = (c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2])
        inc = est.increment
        pose_cov = step if k == 0 else propagate3(self._pose_cov, (inc.x, inc.y, inc.theta), step)
        self._pose_cov = pose_cov
        in_trajectory = covariance_to_parent3(est.pose.theta, pose_cov)
        numbers = ",".join(map(repr, (float(est.stamp), *step, *in_trajectory)))
        why = self._reason(est.reason)
        try:
            self._csv.write(f"{numbers},{why},{1 if est.degraded else 0}\n")
        except OSError as exc:
            raise OutputWriteError(exc.errno, exc.strerror or str(exc), str(self.path)) from exc
        if self.bag is not None:
            self._write_bag(k, est, cov, in_trajectory)

    def _write_bag(self, k: int, est: Estimate, cov: np.ndarray, pose_cov: Cov3Upper) -> None:
        inc = est.increment
        dt = est.stamp - self._stamp
        twist, twist_cov = (0.0, 0.0, 0.0), None
        if k > 0 and dt > 0.0:
            twist, twist_cov = (inc.x / dt, inc.y / dt, inc.theta / dt), cov / (dt * dt)
        self._stamp = est.stamp
        xx, xy, xt, yy, yt, tt = pose_cov
        world_cov = np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]])
        assert self.bag is not None
        self.bag.write(est.stamp, est.pose, world_cov, twist, twist_cov)

    def close_csv(self) -> dict[str, Path]:
        """Finish ``covariance.csv``; name → path where written (on failure, none: the
        temporary file is removed)."""
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

    def close_bag(
        self,
        *,
        partial: bool = False,
        optimised: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None] | None = None,
    ) -> dict[str, Path]:
        """Finish the bag; name → path where written. ``optimised``: loop closure's
        ``(stamps, optimised poses, front end's poses, optimised poses' covariances)``, the
        covariances ``(scans, 3, 3)`` in the map frame
        (:func:`~fuzzypos.graph.outputs.optimised_covariances`; None, or a row not finite:
        unknown), appended first (:meth:`~fuzzypos.io.OdometryBagWriter.write_optimised`).
        One that cannot be finished is removed: noted in a ``partial`` run, else raised."""
        if self.bag is None:
            return {}
        try:
            if optimised is not None:
                stamps, poses, fronts, covs = optimised
                for k, (t, pose, front) in enumerate(zip(stamps, poses, fronts, strict=True)):
                    cov = None if covs is None else covs[k]
                    known = cov is not None and bool(np.all(np.isfinite(cov)))
                    self.bag.write_optimised(float(t), pose, front, cov if known else None)
            self.bag.close()
            self._bag_done = True
        except BaseException as exc:
            self.bag.abort()
            if not partial or not isinstance(exc, Exception):
                raise
            self.notes.append(f"{self.bag.path}: not kept: {' '.join(str(exc).split())}")
            return {}
        return {"bag": self.bag.path}

    def bag_summary(self) -> dict[str, Any] | None:
        """``summary.json``'s ``bag_out``: the bag, its frames and topics (None: no bag)."""
        if self.bag is None:
            return None
        b = self.bag
        topics = {b.pose_topic: b.optimised_written} if b.optimised_written else {}
        return {
            "path": str(b.path),
            "storage": b.storage,
            "frames": self.frames.as_dict(),
            "topics": {b.topic: b.written, "/tf": b.written + b.optimised_written, **topics},
        }

    def close(self, *, partial: bool = False) -> dict[str, Path]:
        """Finish the files (:meth:`close_csv`, :meth:`close_bag`); name → path of those
        written."""
        return {**self.close_csv(), **self.close_bag(partial=partial)}

    def abort(self) -> None:
        """Remove what was written (but a bag already finished)."""
        if self._csv is not None:
            csv, self._csv = self._csv, None
            with contextlib.suppress(OSError):
                csv.close()
            self._tmp.unlink(missing_ok=True)
        if self.bag is not None and not self._bag_done:
            self.bag.abort()


def resolve_bag_frames(reader: object, given: Mapping[str, str | None] | None) -> OutputFrames:
    """The frames of ``run --bag-out`` (:func:`~fuzzypos.io.bag_info.output_frames`):
    ``given`` (``"base"``, ``"odom"``, ``"map"`` → a name or None), else the input bag's (its
    reader's base frame and odometry frames; ``/tf`` read where the map frame is not given),
    else REP-105's."""
    given = dict(given or {})
    if not isinstance(reader, BagReader):
        return output_frames(given)
    if reader.base_frame != (reader.odom_child_frame or "base_link"):
        given.setdefault("base", reader.base_frame)  # given to the reader: its estimate's frame
    tf = read_tf_pairs(reader.path) if given.get("map") is None else []
    return output_frames(
        given, odom_frame=reader.odom_frame, odom_child=reader.odom_child_frame, tf=tf
    )


# -- after the loop --------------------------------------------------------------------------
def is_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is Ctrl-C: a ``KeyboardInterrupt``, or the ``SystemError`` a compiled
    (numba) call raises when one arrives inside it (its cause or context)."""
    if isinstance(exc, KeyboardInterrupt):
        return True
    if isinstance(exc, SystemError):
        return isinstance(exc.__cause__ or exc.__context__, KeyboardInterrupt)
    return False


def as_interrupt(exc: BaseException) -> BaseException:
    """``exc``, but Ctrl-C as the ``KeyboardInterrupt`` itself (:func:`is_interrupt`)."""
    if isinstance(exc, SystemError) and is_interrupt(exc):
        inner = exc.__cause__ or exc.__context__
        assert inner is not None
        return inner
    return exc


def one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


@dataclass(eq=False)
class Steps:
    """The steps after the loop (the final optimisation, each file): one that fails or is
    interrupted (:meth:`run`) is noted, and the first such sets ``stop`` (the exception) and
    ``reason`` (``summary.json``'s ``partial_reason``); the next steps still run, each as it
    would in a partial run. ``stop`` and ``reason`` start as the loop's."""

    stop: BaseException | None = None
    reason: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def partial(self) -> bool:
        return self.reason is not None

    def run(self, what: str, fn: Callable[[], T]) -> T | None:
        """``fn()``, or None where it failed or was interrupted (``what``: the step, as in
        ``"while writing trajectory.tum"``)."""
        try:
            return fn()
        except (Exception, KeyboardInterrupt) as exc:
            self.stopped(what, exc)
            return None

    def done(self, what: str, fn: Callable[[], object]) -> bool:
        """:meth:`run` ``fn``; whether it did not fail."""

        def ran() -> bool:
            fn()
            return True

        return self.run(what, ran) is not None

    def stopped(self, what: str, exc: BaseException) -> None:
        exc = as_interrupt(exc)
        why = f"interrupted {what}" if isinstance(exc, KeyboardInterrupt) else f"failed {what}"
        why += "" if isinstance(exc, KeyboardInterrupt) else f": {one_line(exc)}"
        if self.stop is None:
            self.stop, self.reason = exc, why
        self.notes.append(why)
