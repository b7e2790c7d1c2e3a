"""Relations files: the ground truth of the Freiburg SLAM benchmark.

Format (the shared data's ``README.md``, Kümmerle et al. 2009): one relation per line,
``t1 t2 x y z roll pitch yaw`` = the true motion of the robot from the scan at time ``t1`` to
the scan at time ``t2``, expressed in the frame of the first (``x, y`` in metres, ``yaw`` in
radians). :func:`read_relations` reads them into a :class:`Relations`;
:func:`fuzzypos.eval.metrics.relations_errors` scores a trajectory against them.

Validation is strict; anything else raises :class:`RelationsFormatError` naming the file, the
1-based line and what is wrong:

- every line that is neither blank nor a ``#`` comment holds exactly 8 fields, each a finite
  number;
- the relation must be planar: ``|z|``, ``|roll|`` and ``|pitch|`` at most
  :data:`PLANAR_TOLERANCE` (1e-6; the benchmark writes them as ``0.000000``). A 2D evaluator
  cannot score a 3D motion, so a non-planar relation is an error rather than silently
  projected.

Nothing constrains the order of ``t1`` and ``t2``: intel has 6 relations with ``t2 < t1``
(by under 0.9 s, its clocks go backwards), and they are scored like any other. The file's
order is kept; ``yaw`` is wrapped to ``[-π, π)``. Plain or gzip, by magic bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import wrap_angle
from ._common import FloatArray, LogFormatError, PathLike, numeric_rows

__all__ = ["PLANAR_TOLERANCE", "Relations", "RelationsFormatError", "read_relations"]

#: Largest ``|z|`` (m), ``|roll|`` and ``|pitch|`` (rad) a relation may have to count as planar.
PLANAR_TOLERANCE = 1e-6

_FIELDS = ("t1", "t2", "x", "y", "z", "roll", "pitch", "yaw")


class RelationsFormatError(LogFormatError):
    """A malformed relations line, e.g. ``intel.relations:3: expected 8 fields …, got 7``."""


def _frozen(a: FloatArray) -> FloatArray:
    a = np.array(a, dtype=np.float64)  # a copy: the caller's array stays writable and apart
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Relations:
    """Relations of the benchmark: relation ``i`` is the true motion ``motion[i] = (x, y, yaw)``
    of the robot from the scan at time ``t1[i]`` to the scan at time ``t2[i]``, in the frame
    of the first. ``t1``, ``t2`` have shape ``(n,)``, ``motion`` ``(n, 3)``; all finite. The
    arrays are read-only copies."""

    t1: FloatArray
    t2: FloatArray
    motion: FloatArray

    def __post_init__(self) -> None:
        t1 = np.asarray(self.t1, dtype=np.float64)
        t2 = np.asarray(self.t2, dtype=np.float64)
        m = np.asarray(self.motion, dtype=np.float64)
        if m.ndim == 1 and m.size == 0:
            m = m.reshape(0, 3)
        if t1.ndim != 1 or t2.shape != t1.shape:
            raise ValueError(
                f"t1 and t2 must have the same shape (n,), got {t1.shape} and {t2.shape}"
            )
        if m.shape != (t1.shape[0], 3):
            raise ValueError(
                f"motion must have shape ({t1.shape[0]}, 3) (x, y, yaw), got {m.shape}"
            )
        if not (np.isfinite(t1).all() and np.isfinite(t2).all() and np.isfinite(m).all()):
            raise ValueError("relations must be finite")
        object.__setattr__(self, "t1", _frozen(t1))
        object.__setattr__(self, "t2", _frozen(t2))
        object.__setattr__(self, "motion", _frozen(m))

    def __len__(self) -> int:
        return int(self.t1.shape[0])

    @property
    def dt(self) -> FloatArray:
        """``t2 − t1`` (s), signed."""
        return self.t2 - self.t1

    def is_local(self, max_dt: float = 10.0) -> np.ndarray:
        """The benchmark's "local" relations: ``t2 − t1 <= max_dt`` (s), as a bool mask."""
        return self.dt <= max_dt


def read_relations(path: PathLike) -> Relations:
    """Read a relations file ``t1 t2 x y z roll pitch yaw`` (module docstring) into
    :class:`Relations`, in file order. Raises :class:`RelationsFormatError` naming the file
    and line for a wrong field count, a field that is not a finite number, or a non-planar
    relation. A file with no relations gives an empty :class:`Relations`."""
    t1: list[float] = []
    t2: list[float] = []
    rows: list[tuple[float, float, float]] = []
    for lineno, vals in numeric_rows(path, _FIELDS, RelationsFormatError):
        a, b, x, y, z, roll, pitch, yaw = vals
        for what, v in (("z", z), ("roll", roll), ("pitch", pitch)):
            if abs(v) > PLANAR_TOLERANCE:
                raise RelationsFormatError(
                    path,
                    lineno,
                    f"relation is not planar: {what} = {v!r} "
                    f"(|{what}| must be <= {PLANAR_TOLERANCE:g})",
                )
        t1.append(a)
        t2.append(b)
        rows.append((x, y, yaw))
    motion = np.array(rows, dtype=np.float64).reshape(-1, 3)
    if motion.shape[0]:
        motion[:, 2] = wrap_angle(motion[:, 2])
    return Relations(np.array(t1, dtype=np.float64), np.array(t2, dtype=np.float64), motion)
