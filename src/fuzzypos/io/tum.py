"""TUM trajectories.

``t x y z qx qy qz qw`` per line (the format ``evo`` reads): :func:`write_tum` writes planar
poses (``z = qx = qy = 0``, ``qz = sin(θ/2)``, ``qw = cos(θ/2)``) at full precision;
:func:`read_tum` reads them back with strict validation (:class:`TumFormatError`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import IO

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import Pose2D, wrap_angle
from ._common import FloatArray, LogFormatError, PathLike, _write_atomically, numeric_rows

__all__ = ["TumFormatError", "read_tum", "write_tum"]


class TumFormatError(LogFormatError):
    """A malformed TUM trajectory line, e.g. ``traj.tum:3: expected 8 fields …, got 7``."""


def _poses_array(poses: ArrayLike | Sequence[Pose2D]) -> FloatArray:
    if isinstance(poses, (list, tuple)) and poses and isinstance(poses[0], Pose2D):
        return np.array([p.as_array() for p in poses], dtype=np.float64).reshape(-1, 3)
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim == 1 and arr.size == 0:
        arr = arr.reshape(0, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"poses must have shape (n, 3) (x, y, theta), got {arr.shape}")
    return arr


def write_tum(
    path: PathLike,
    stamps: ArrayLike,
    poses: ArrayLike | Sequence[Pose2D],
    *,
    header_comment: str | None = None,
) -> None:
    """Write planar poses as a TUM trajectory: ``t x y z qx qy qz qw`` per line.

    ``stamps`` has shape ``(n,)``, ``poses`` ``(n, 3)`` (``x, y, θ``) or is a sequence of
    :class:`~fuzzypos.geometry.Pose2D`. ``z = qx = qy = 0``, ``qz = sin(θ/2)``,
    ``qw = cos(θ/2)``; stamps and coordinates at full precision (``repr``), never rounded.
    ``header_comment`` lines become ``#`` comments at the top (``evo`` skips them). Non-finite
    values raise :class:`ValueError`. A name ending in ``.gz`` gets a gzip file.
    """
    t = np.asarray(stamps, dtype=np.float64)
    if t.ndim != 1:
        raise ValueError(f"stamps must have shape (n,), got {t.shape}")
    p = _poses_array(poses)
    if t.shape[0] != p.shape[0]:
        raise ValueError(f"got {t.shape[0]} stamps for {p.shape[0]} poses")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise ValueError("stamps and poses must be finite")

    def write(fh: IO[str]) -> None:
        if header_comment:
            for line in str(header_comment).splitlines():
                fh.write(f"# {line}\n" if line else "#\n")
        for ti, (x, y, th) in zip(t.tolist(), p.tolist()):
            qz, qw = math.sin(th / 2.0), math.cos(th / 2.0)
            fh.write(f"{ti!r} {x!r} {y!r} 0.0 0.0 0.0 {qz!r} {qw!r}\n")

    _write_atomically(path, write)


def read_tum(path: PathLike) -> tuple[FloatArray, FloatArray]:
    """Read a TUM trajectory: ``(stamps (n,), poses (n, 3))`` with ``θ`` the quaternion's yaw.

    Every non-comment line must hold exactly 8 finite numbers ``t x y z qx qy qz qw`` with a
    unit quaternion (to 1e-3; it is normalised before use); lines starting with ``#`` and
    blank lines are skipped; ``z``, roll and pitch are dropped. Anything else raises
    :class:`TumFormatError` naming the file and line. Plain or gzip (by magic bytes); the
    order of the file is kept (stamps need not increase).
    """
    stamps: list[float] = []
    rows: list[tuple[float, float, float]] = []
    for lineno, vals in numeric_rows(
        path, ("t", "x", "y", "z", "qx", "qy", "qz", "qw"), TumFormatError
    ):
        t, x, y, _z, qx, qy, qz, qw = vals
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if abs(norm - 1.0) > 1e-3:
            raise TumFormatError(
                path,
                lineno,
                f"quaternion (qx qy qz qw) is not a unit quaternion: norm {norm:.6g}",
            )
        qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
        yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        stamps.append(t)
        rows.append((x, y, yaw))
    t_arr = np.array(stamps, dtype=np.float64)
    poses = np.array(rows, dtype=np.float64).reshape(-1, 3)
    if poses.shape[0]:
        poses[:, 2] = wrap_angle(poses[:, 2])
    return t_arr, poses
