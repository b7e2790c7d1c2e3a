"""What the run job's outputs (:mod:`fuzzypos.jobs.run`, its sinks :mod:`fuzzypos.jobs.sinks`)
share: ``covariance.csv``'s columns, the bag's frames (:func:`resolve_bag_frames`), Ctrl-C
told apart (:func:`is_interrupt`), and the steps after the loop (:class:`Steps`): each one
that fails or is interrupted is noted and makes the run partial, and the others still run,
so that what was done is kept."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TypeVar

from ..io import BagReader
from ..io.bag_info import OutputFrames, output_frames, read_tf_pairs

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
