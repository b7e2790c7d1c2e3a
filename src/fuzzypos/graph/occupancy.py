"""An occupancy grid from scans at their (optimised) poses (a run's: every scan that moved
``[loop_closure] map_scan_distance`` or turned ``map_scan_angle``; offline, the keyframes'),
written as ROS map_server's ``map.pgm`` + ``map.yaml`` and as ``map.png``. A run without loop
closure draws the same scans at the front end's poses (``fuzzypos run --save-map``):
:class:`MapScans` chooses them for both. Nothing here needs gtsam.

Each scan's points (robot frame) are cast from the robot's position: the cells a beam
crosses gather evidence of free space, the cell it ends in of an obstacle (log-odds, clamped);
the laser's mount offset is neglected (centimetres against the 5 cm cells)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..geometry import relative, transform_points

__all__ = ["MapScans", "OccupancyGrid", "map_grid", "occupancy_grid"]

FloatArray = NDArray[np.float64]

#: log-odds per hit, per pass and the bound either way: from scans a fraction of a metre apart
#: (or keyframes, a metre), two passes make a cell free, one hit an obstacle
_HIT, _MISS, _CLAMP = 2.0, -0.75, 5.0
#: map_server's thresholds (written into map.yaml) and its grey levels (free, unknown, occupied)
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196
_FREE, _UNKNOWN, _OCCUPIED = 254, 205, 0


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """Log-odds per cell (rows from the bottom, ``y`` up), the cells' side (m) and the world
    position of the lower-left corner of cell (0, 0)."""

    log_odds: FloatArray
    resolution: float
    origin: tuple[float, float]

    def image(self) -> NDArray[np.uint8]:
        """The grid as map_server's grey levels, top row first (254 free, 0 occupied, 205
        unknown)."""
        p = 1.0 - 1.0 / (1.0 + np.exp(self.log_odds))
        img = np.full(p.shape, _UNKNOWN, dtype=np.uint8)
        img[p > OCCUPIED_THRESH] = _OCCUPIED
        img[p < FREE_THRESH] = _FREE
        out: NDArray[np.uint8] = img[::-1].copy()
        return out

    def write(self, folder: Path, name: str = "map") -> dict[str, Path]:
        """``name.pgm`` (binary P5), ``name.yaml`` and ``name.png`` in ``folder``."""
        img = self.image()
        pgm, yaml, png = (folder / f"{name}.{ext}" for ext in ("pgm", "yaml", "png"))
        h, w = img.shape
        pgm.write_bytes(f"P5\n# fuzzypos occupancy map\n{w} {h}\n255\n".encode() + img.tobytes())
        yaml.write_text(
            f"image: {pgm.name}\nresolution: {self.resolution:.6g}\n"
            f"origin: [{self.origin[0]:.6f}, {self.origin[1]:.6f}, 0.0]\nnegate: 0\n"
            f"occupied_thresh: {OCCUPIED_THRESH}\nfree_thresh: {FREE_THRESH}\n",
            encoding="utf-8",
        )
        import matplotlib.image

        matplotlib.image.imsave(png, img, cmap="gray", vmin=0, vmax=255)
        return {pgm.name: pgm, yaml.name: yaml, png.name: png}


def occupancy_grid(
    poses: FloatArray, scans: list[FloatArray], resolution: float, margin: float = 1.0
) -> OccupancyGrid:
    """The grid over every ``scans[k]`` (points in the robot frame) seen from ``poses[k]``."""
    world = [transform_points(p, s) for p, s in zip(poses, scans) if s.shape[0]]
    everything = np.vstack([poses[:, :2], *world]) if world else poses[:, :2]
    lo = everything.min(axis=0) - margin
    hi = everything.max(axis=0) + margin
    shape = (
        math.ceil((hi[1] - lo[1]) / resolution),
        math.ceil((hi[0] - lo[0]) / resolution),
    )
    grid = np.zeros(shape)
    for pose, pts in zip(poses, world):
        _cast(grid, pose[:2], pts, lo, resolution)
    return OccupancyGrid(np.clip(grid, -_CLAMP, _CLAMP), resolution, (float(lo[0]), float(lo[1])))


class MapScans:
    """The scans a map is drawn from, as they come: each whose pose (the front end's) moved
    ``distance`` or turned ``angle`` since the last one kept (``[loop_closure]
    map_scan_distance``, ``map_scan_angle``); ``scans``: its index and its points in the
    robot frame."""

    def __init__(self, distance: float, angle: float) -> None:
        self.distance, self.angle = distance, angle
        self.scans: list[tuple[int, FloatArray]] = []
        self._last: FloatArray | None = None

    def add(self, k: int, pose: FloatArray, points: FloatArray | None) -> bool:
        """Keep scan ``k`` (its ``points``, None or none: never) where ``pose`` is far enough
        from the last kept; whether it was kept."""
        if points is None or not points.shape[0]:
            return False
        pose = np.asarray(pose, dtype=np.float64)
        if self._last is not None:
            d = relative(self._last, pose)
            if math.hypot(d[0], d[1]) < self.distance and abs(d[2]) < self.angle:
                return False
        self._last = pose
        self.scans.append((k, points))
        return True


def map_grid(
    poses: FloatArray, scans: list[tuple[int, FloatArray]], resolution: float
) -> OccupancyGrid:
    """The grid of ``scans`` (:attr:`MapScans.scans`), each at its pose in ``poses`` (every
    scan's, ``(scans, 3)``); without any, an unknown grid around the first pose."""
    if not scans:
        return occupancy_grid(poses[:1].reshape(-1, 3), [np.zeros((0, 2))], resolution)
    at = poses[[k for k, _ in scans]].reshape(-1, 3)
    return occupancy_grid(at, [points for _, points in scans], resolution)


def _cast(
    grid: FloatArray, origin: FloatArray, pts: FloatArray, lo: FloatArray, res: float
) -> None:
    """One scan's evidence: the cells along each beam (sampled every half cell from the
    robot, short of the end cell) free, each cell once per scan, the end cells occupied."""
    d = pts - origin
    length = np.hypot(d[:, 0], d[:, 1])
    step = 0.5 * res
    counts = np.maximum(np.ceil((length - res) / step), 0).astype(np.int64)
    beam = np.repeat(np.arange(len(pts)), counts)
    along = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    f = along * step / length[beam]
    samples = origin + f[:, None] * d[beam]
    cells = np.floor((samples - lo) / res).astype(np.int64)
    ends = np.floor((pts - lo) / res).astype(np.int64)
    n_cols = grid.shape[1]
    free = cells[:, 1] * n_cols + cells[:, 0]
    hit = ends[:, 1] * n_cols + ends[:, 0]
    flat = grid.reshape(-1)
    before = flat[hit]
    flat[free] += _MISS  # a repeated index is added once (buffered fancy indexing)
    flat[hit] = before + _HIT  # an end cell is not free in the same scan
