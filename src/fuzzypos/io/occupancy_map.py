"""An occupancy map as ROS map_server saves it: ``MAP.yaml`` beside its image (pgm or png).

:class:`OccupancyMap` holds the cells as ``nav_msgs/OccupancyGrid`` does: -1 unknown, 0 free up
to 100 occupied, row 0 the map's bottom row (``y`` up), with the cells' side and the pose of
cell (0, 0)'s lower-left corner in the map frame (``origin``: x, y and yaw, as the yaml's).
:func:`read_map_yaml` reads one as map_server does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["FREE", "OCCUPIED", "UNKNOWN", "OccupancyMap", "read_map_yaml"]

#: the cells' values (``nav_msgs/OccupancyGrid``)
UNKNOWN, FREE, OCCUPIED = -1, 0, 100


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy map: ``cells`` (int8, rows from the bottom: -1 unknown, 0..100 the chance
    of an obstacle in percent), ``resolution`` (m per cell) and ``origin`` (x, y in m, yaw in
    rad: the pose of cell (0, 0)'s lower-left corner in the map frame); ``source`` the yaml
    it was read from, if any."""

    cells: NDArray[np.int8]
    resolution: float
    origin: tuple[float, float, float]
    source: Path | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """Rows and columns."""
        return (int(self.cells.shape[0]), int(self.cells.shape[1]))

    def occupied(self, threshold: int = 50) -> NDArray[np.bool_]:
        """The cells whose value is at least ``threshold`` (percent)."""
        out: NDArray[np.bool_] = self.cells >= threshold
        return out

    def to_map(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Grid coordinates (column, row, in cells, fractional) of map-frame ``points``."""
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        d = np.asarray(points, dtype=np.float64) - (x0, y0)
        local = np.column_stack((c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]))
        out: NDArray[np.float64] = local / self.resolution
        return out

    def cell_centres(self, rows: NDArray[np.int64], cols: NDArray[np.int64]) -> NDArray[np.float64]:
        """The map-frame positions of the centres of cells (``rows``, ``cols``)."""
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        u = (np.asarray(cols, dtype=np.float64) + 0.5) * self.resolution
        v = (np.asarray(rows, dtype=np.float64) + 0.5) * self.resolution
        return np.column_stack((x0 + c * u - s * v, y0 + s * u + c * v))


def read_map_yaml(path: str | Path) -> OccupancyMap:
    """The map of a map_server ``yaml`` (``image``, ``resolution``, ``origin``, ``negate``,
    ``occupied_thresh``, ``free_thresh``; ``mode`` trinary only so far)."""
    import yaml  # type: ignore[import-untyped]
    from PIL import Image

    path = Path(path)
    meta = yaml.safe_load(path.read_text(encoding="utf-8"))
    image = Path(meta["image"])
    if not image.is_absolute():
        image = path.parent / image
    pixels = np.asarray(Image.open(image).convert("L"), dtype=np.float64)
    negate = bool(int(meta.get("negate", 0)))
    occ = (pixels / 255.0) if negate else (255.0 - pixels) / 255.0
    cells = np.full(pixels.shape, UNKNOWN, dtype=np.int8)
    cells[occ > float(meta["occupied_thresh"])] = OCCUPIED
    cells[occ < float(meta["free_thresh"])] = FREE
    x, y, yaw = (float(v) for v in meta["origin"])
    return OccupancyMap(cells[::-1].copy(), float(meta["resolution"]), (x, y, yaw), path)
