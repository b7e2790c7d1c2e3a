"""Whether a scan agrees with the map at a pose, in absolute terms (not only better than
elsewhere): how many of its points end on a wall (within ``near`` of an occupied cell), how
many end in free space away from every wall (the map says nothing is there), and how many of
its beams pass through a wall (an occupied cell on the beam farther than ``near`` from both
its ends, for it and the beams ``near`` beside it: the map says the laser could not have seen
that far). At the right pose nearly all points end on walls and almost no beam crosses one;
in another building, or at a wrong place whose walls fit nearby, many are contradicted (the
free-space test of place-recognition verifiers). Compiled:
:func:`fuzzypos._kernels.agreement.agreement`."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._kernels import agreement as _kernel
from .field import MapField

FloatArray = NDArray[np.float64]


class Agreement(NamedTuple):
    """Counts over one scan's points at one pose: ``points``, those ending on a wall
    (``hits``), the beams crossing one (``through``) and the points ending in free space
    farther than ``near`` from every wall (``strays``)."""

    points: int
    hits: int
    through: int
    strays: int


def agreement(
    field: MapField, points: FloatArray, sensor: FloatArray, pose: FloatArray, near: float
) -> Agreement:
    """The scan's ``points`` (robot frame; their beams start at ``sensor``, robot frame (x, y))
    at ``pose`` (grid frame) against the map (module docstring)."""
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    hits, through, strays = _kernel.agreement(
        pts,
        np.ascontiguousarray(sensor[:2], dtype=np.float64),
        np.ascontiguousarray(pose[:3], dtype=np.float64),
        field.walls.distance,
        field.free,
        float(field.walls.geometry[0]),
        float(near),
    )
    return Agreement(int(pts.shape[0]), int(hits), int(through), int(strays))
