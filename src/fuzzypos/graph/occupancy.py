"""An occupancy grid from the keyframes' scans at their (optimised) poses, written as ROS
map_server's ``map.pgm`` + ``map.yaml`` and as ``map.png``.

Each keyframe's points (robot frame) are cast from the robot's position: the cells a beam
crosses gather evidence of free space, the cell it ends in of an obstacle (log-odds, clamped);
the laser's mount offset is neglected (centimetres against the 5 cm cells)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..geometry import transform_points

__all__ = ["OccupancyGrid", "occupancy_grid"]

FloatArray = NDArray[np.float64]

#: log-odds per hit, per pass and the bound either way: from keyframes only (a scan every metre
#: or 30°), two passes make a cell free, one hit an obstacle
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


def _cast(
    grid: FloatArray, origin: FloatArray, pts: FloatArray, lo: FloatArray, res: float
) -> None:
    """One scan's evidence: the cells along each beam (sampled every half cell, each cell once
    per scan) free, the end cells occupied."""
    d = pts - origin
    length = np.hypot(d[:, 0], d[:, 1])
    steps = max(1, math.ceil(float(length.max(initial=0.0)) / (0.5 * res)))
    f = np.linspace(0.0, 1.0, steps, endpoint=False)
    samples = origin + f[None, :, None] * d[:, None, :]  # beams × steps × 2
    inside = f[None, :] * length[:, None] < length[:, None] - res  # short of the end cell
    cells = np.floor((samples[inside] - lo) / res).astype(np.int64)
    ends = np.floor((pts - lo) / res).astype(np.int64)
    _n_rows, n_cols = grid.shape
    free = np.unique(cells[:, 1] * n_cols + cells[:, 0])
    hit = np.unique(ends[:, 1] * n_cols + ends[:, 0])
    free = np.setdiff1d(free, hit)
    flat = grid.reshape(-1)
    flat[free] += _MISS
    flat[hit] += _HIT
