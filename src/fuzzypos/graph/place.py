"""Place recognition for loop closure where the drift exceeds any gate: a rotation-invariant
descriptor of the place around a keyframe (``[loop_closure]``'s ``place_*`` fields).

A keyframe's place is the points of its scan and of the ``place_keyframes`` keyframes before
it, in its frame (the front end's poses: over a few metres they are exact to centimetres), so
a scanner that sees less than a full turn still describes most of the place around it. The
descriptor is a polar occupancy grid of those points, ``place_rings`` rings out to
``place_range`` by ``place_sectors`` sectors of bearing (Scan Context's ring × sector layout,
with occupancy instead of height: a 2D scan has none), each cell shared with its neighbours
(a ¼ ½ ¼ kernel along both axes: a viewpoint a few decimetres off moves points into the next
cell, and without it the same room from 0.4 m away scored like another room), each sector's
column normalised. Two
places are compared at every sector shift: the mean, over the sectors both see, of the cosine
similarity of their columns; the distance is one minus the best, and the best shift is the
heading between them. The distance is rotation-invariant (exactly for turns by whole sectors)
and the shift gives the verification its start where the graph's guess is metres off.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["PlaceDescriptor", "PlaceIndex", "place_descriptor"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PlaceDescriptor:
    """A place's polar occupancy grid, ``columns`` ``(sectors, rings)`` with each non-empty
    sector's column of unit length, and which sectors see anything (``seen``)."""

    columns: FloatArray
    seen: FloatArray

    @property
    def sectors(self) -> int:
        return int(self.columns.shape[0])

    @property
    def sector_width(self) -> float:
        return math.tau / self.sectors


def place_descriptor(
    points: FloatArray, rings: int, sectors: int, max_range: float
) -> PlaceDescriptor:
    """The descriptor of ``points`` ``(n, 2)`` in the place's frame (module docstring): points
    beyond ``max_range`` (or at the origin) are left out."""
    if rings < 1 or sectors < 1 or not max_range > 0.0:
        raise ValueError(
            f"a place descriptor needs rings, sectors >= 1 and a range > 0, got "
            f"{rings}, {sectors}, {max_range}"
        )
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    r = np.hypot(pts[:, 0], pts[:, 1])
    ok = (r > 0.0) & (r < max_range) & np.isfinite(r)
    bearing = np.arctan2(pts[ok, 1], pts[ok, 0]) % math.tau
    ring = np.minimum((r[ok] / max_range * rings).astype(np.intp), rings - 1)
    sector = np.minimum((bearing / math.tau * sectors).astype(np.intp), sectors - 1)
    grid = np.zeros((sectors, rings))
    grid[sector, ring] = 1.0
    # each cell shared with its neighbours, ¼ ½ ¼ along the sectors (circular) and the rings:
    # a viewpoint a few decimetres off moves points across a cell's border, not further
    grid = 0.5 * grid + 0.25 * (np.roll(grid, 1, 0) + np.roll(grid, -1, 0))
    padded = np.pad(grid, ((0, 0), (1, 1)), mode="edge")
    grid = 0.5 * grid + 0.25 * (padded[:, :-2] + padded[:, 2:])
    norm = np.linalg.norm(grid, axis=1)
    seen = (norm > 0.0).astype(float)
    columns = grid / np.where(norm > 0.0, norm, 1.0)[:, None]
    return PlaceDescriptor(columns, seen)


class PlaceIndex:
    """The descriptors of a run's keyframes, compared at every sector shift at once (the
    circular cross-correlations along the sectors, by FFT)."""

    def __init__(self, descriptors: Sequence[PlaceDescriptor]) -> None:
        if not descriptors:
            raise ValueError("a place index needs at least one descriptor")
        sectors = {d.columns.shape for d in descriptors}
        if len(sectors) != 1:
            raise ValueError(f"the descriptors' grids differ: {sorted(sectors)}")
        self.descriptors: list[PlaceDescriptor] = []
        # each descriptor's spectra along the sectors, kept apart so that the index grows by
        # one keyframe at a time (online) without redoing the others
        self._columns: list[NDArray[np.complex128]] = []
        self._seen: list[NDArray[np.complex128]] = []
        self._sectors = descriptors[0].sectors
        for d in descriptors:
            self.append(d)

    def __len__(self) -> int:
        return len(self.descriptors)

    def append(self, descriptor: PlaceDescriptor) -> None:
        """One more keyframe's descriptor (the next index)."""
        shape = self.descriptors[0].columns.shape if self.descriptors else None
        if shape is not None and descriptor.columns.shape != shape:
            raise ValueError(f"the descriptors' grids differ: {shape}, {descriptor.columns.shape}")
        self.descriptors.append(descriptor)
        self._columns.append(np.fft.rfft(descriptor.columns, axis=0))
        self._seen.append(np.fft.rfft(descriptor.seen))

    def compare(
        self, query: PlaceDescriptor, among: NDArray[np.intp], min_overlap: float
    ) -> tuple[FloatArray, FloatArray]:
        """For each descriptor of ``among``: the distance to ``query`` (one minus the best
        mean cosine similarity over the sectors both see, 1 where they share fewer than
        ``min_overlap`` of the sectors either sees) and the heading of the query's place in
        the other's frame at that shift (rad, within ±π)."""
        n = self._sectors
        fq = np.fft.rfft(query.columns, axis=0)
        fs = np.fft.rfft(query.seen)
        # sim[k, m] = Σ_c <q[c], d_k[c + m]>: a turn of the query's frame by +m sectors
        columns = np.stack([self._columns[k] for k in among])
        seen = np.stack([self._seen[k] for k in among])
        dots = np.fft.irfft((np.conj(fq)[None] * columns).sum(axis=2), n, axis=1)
        both = np.fft.irfft(np.conj(fs)[None] * seen, n, axis=1)
        both = np.rint(both)
        either = np.minimum(query.seen.sum(), np.array([self.descriptors[k].seen.sum()
                                                         for k in among]))  # fmt: skip
        enough = both >= min_overlap * np.maximum(either, 1.0)[:, None]
        sim = np.where(enough & (both > 0), dots / np.maximum(both, 1.0), -np.inf)
        best = np.argmax(sim, axis=1)
        top = sim[np.arange(len(among)), best]
        distance = np.where(np.isfinite(top), 1.0 - top, 1.0)
        shift = np.where(best > n // 2, best - n, best).astype(float)
        return distance, shift * (math.tau / n)
