"""The map as the localizer reads it: the distance from every cell to the nearest wall, each
occupied cell's wall line (a point and a normal, from the occupied cells around it), the
global search's max-pooled likelihood grids, and the cache of the first two beside the map
file (``<map>.fuzzypos-field.npz``, keyed by a hash of the yaml and its image and of the
settings that shape them: a second start reads it; a folder it cannot write to is no
error, the field is then computed each time)."""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from .._kernels.localize import SearchGrids, WallField
from ..config.localization import LocalizationConfig
from ..geometry import Pose2D, compose, inverse
from ..io.occupancy_map import FREE, OccupancyMap

__all__ = ["MapField", "field_of", "CACHE_SUFFIX"]

FloatArray = NDArray[np.float64]
#: the cache file beside ``MAP.yaml`` is ``MAP.yaml`` + this
CACHE_SUFFIX = ".fuzzypos-field.npz"
#: bumped whenever what the cache holds changes
_CACHE_VERSION = 1
#: a cell counts as occupied from this value (percent), as map_server's trinary maps write 100
OCCUPIED_FROM = 50


@dataclass(frozen=True, eq=False)
class MapField:
    """The map's walls (:class:`~fuzzypos._kernels.localize.WallField`), its free cells and
    the transform between the map frame and the grid frame (the map's origin)."""

    occupancy_map: OccupancyMap
    walls: WallField
    free: NDArray[np.bool_]
    free_distance: FloatArray

    @property
    def resolution(self) -> float:
        return float(self.occupancy_map.resolution)

    @property
    def origin(self) -> FloatArray:
        return np.asarray(self.occupancy_map.origin, dtype=np.float64)

    @property
    def size(self) -> tuple[float, float]:
        """The map's width and height (m)."""
        rows, cols = self.free.shape
        return cols * self.resolution, rows * self.resolution

    def to_grid(self, pose: FloatArray) -> FloatArray:
        """A map-frame pose in the grid frame."""
        return compose(inverse(self.origin), np.asarray(pose, dtype=np.float64))

    def to_map(self, pose: FloatArray) -> FloatArray:
        """A grid-frame pose in the map frame."""
        return compose(self.origin, np.asarray(pose, dtype=np.float64))

    def distance_to_free(self, grid_pose: FloatArray) -> float:
        """How far (m) a grid-frame position lies from the nearest free cell (inf off the map)."""
        rows, cols = self.free.shape
        c = math.floor(grid_pose[0] / self.resolution)
        r = math.floor(grid_pose[1] / self.resolution)
        if not (0 <= r < rows and 0 <= c < cols):
            return math.inf
        return float(self.free_distance[r, c])

    def pose_of(self, grid_pose: FloatArray) -> Pose2D:
        return Pose2D.from_array(self.to_map(grid_pose))

    def search_grids(self, cell: float, sigma: float, levels: int) -> tuple[SearchGrids, int]:
        """The global search's grids at ``cell`` metres (a whole number of map cells, at
        least one), the likelihood exp(−d²/2σ²) max-pooled into them, and ``levels`` levels
        of blocks; returns the grids and the number of map cells per search cell."""
        factor = max(1, round(cell / self.resolution))
        like = np.exp(-0.5 * (self.walls.distance / sigma) ** 2)
        score0 = _pool(like, factor)
        free0 = _pool(self.free.astype(np.float64), factor)
        score = [score0]
        free = [free0]
        for h in range(1, levels + 1):
            half = 1 << (h - 1)
            score.append(_shift_max(score[-1], half))
            free.append(_shift_max(free[-1], half))
        return SearchGrids(np.stack(score), np.stack(free)), factor


def _pool(grid: FloatArray, factor: int) -> FloatArray:
    """The maximum of ``grid`` over blocks of ``factor`` × ``factor`` cells (edges padded 0)."""
    if factor == 1:
        return np.ascontiguousarray(grid, dtype=np.float64)
    rows, cols = grid.shape
    pr, pc = -rows % factor, -cols % factor
    padded = np.pad(grid, ((0, pr), (0, pc)))
    r2, c2 = padded.shape[0] // factor, padded.shape[1] // factor
    out: FloatArray = padded.reshape(r2, factor, c2, factor).max(axis=(1, 3))
    return np.ascontiguousarray(out, dtype=np.float64)


def _shift_max(grid: FloatArray, half: int) -> FloatArray:
    """The maximum over (r, c), (r + half, c), (r, c + half), (r + half, c + half) (0 past
    the grid): one level of blocks from the one below."""
    out = grid.copy()
    out[:-half, :] = np.maximum(out[:-half, :], grid[half:, :])
    right = out.copy()
    out[:, :-half] = np.maximum(out[:, :-half], right[:, half:])
    return np.ascontiguousarray(out)


def _walls(occupied: NDArray[np.bool_], resolution: float, radius: float) -> FloatArray:
    """Each occupied cell's wall line (x, y, n_x, n_y in the grid frame, row-major order):
    the mean and the least-variance direction of the occupied cells within ``radius``
    (second moments by correlation with a disc), a zero normal where it stands alone."""
    k = max(1, int(radius / resolution))
    dy, dx = np.mgrid[-k : k + 1, -k : k + 1].astype(np.float64)
    disc = (dx**2 + dy**2 <= k * k + 1e-9).astype(np.float64)
    occ = occupied.astype(np.float64)

    def corr(kernel: FloatArray) -> FloatArray:
        out: FloatArray = ndimage.correlate(occ, kernel, mode="constant")
        return out

    n = corr(disc)
    sx, sy = corr(disc * dx), corr(disc * dy)
    sxx, syy, sxy = corr(disc * dx * dx), corr(disc * dy * dy), corr(disc * dx * dy)
    rows, cols = np.nonzero(occupied)
    nn = n[rows, cols]
    mx, my = sx[rows, cols] / nn, sy[rows, cols] / nn
    cxx = sxx[rows, cols] / nn - mx * mx
    cyy = syy[rows, cols] / nn - my * my
    cxy = sxy[rows, cols] / nn - mx * my
    major = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    spread = np.hypot(0.5 * (cxx - cyy), cxy)
    lam_min = 0.5 * (cxx + cyy) - spread
    lam_max = 0.5 * (cxx + cyy) + spread
    line = (nn >= 3) & (lam_max > 0.5) & (lam_min < 0.5 * lam_max)
    nx = np.where(line, -np.sin(major), 0.0)
    ny = np.where(line, np.cos(major), 0.0)
    px = (cols + 0.5 + np.where(line, mx, 0.0)) * resolution
    py = (rows + 0.5 + np.where(line, my, 0.0)) * resolution
    out: FloatArray = np.column_stack((px, py, nx, ny))
    return np.ascontiguousarray(out)


def compute_field(occupancy_map: OccupancyMap, cfg: LocalizationConfig) -> dict[str, NDArray]:
    """The arrays a :class:`MapField` is made of (what the cache holds)."""
    res = float(occupancy_map.resolution)
    free = occupancy_map.cells == FREE
    # the walls' faces: occupied cells beside free space (a scan sees no wall's inside)
    occupied = (occupancy_map.cells >= OCCUPIED_FROM) & ndimage.binary_dilation(
        free, structure=np.ones((3, 3), dtype=bool)
    )
    if not occupied.any():  # no free space drawn: every occupied cell is a wall
        occupied = occupancy_map.cells >= OCCUPIED_FROM
    cap = float(cfg.field_distance)
    if occupied.any():
        dist, (ir, ic) = ndimage.distance_transform_edt(
            ~occupied, sampling=res, return_indices=True
        )
    else:
        dist = np.full(occupied.shape, np.inf)
        ir = ic = np.zeros(occupied.shape, dtype=np.int64)
    index = np.full(occupied.shape, -1, dtype=np.int64)
    index[occupied] = np.arange(int(occupied.sum()))
    nearest = np.where(dist <= cap, index[ir, ic], -1).astype(np.int64)
    if free.any():
        free_distance = ndimage.distance_transform_edt(~free, sampling=res)
    else:
        free_distance = np.full(free.shape, np.inf)
    return {
        "distance": np.minimum(dist, cap).astype(np.float64),
        "nearest": nearest,
        "wall": _walls(occupied, res, float(cfg.wall_radius)),
        "free": free,
        "free_distance": free_distance.astype(np.float64),
    }


def _cache_key(occupancy_map: OccupancyMap, cfg: LocalizationConfig) -> str | None:
    """The hash of the map's yaml and image files and of the settings the field depends on
    (None: the map has no file, or it cannot be read)."""
    source = occupancy_map.source
    if source is None:
        return None
    digest = hashlib.sha256()
    try:
        digest.update(Path(source).read_bytes())
        image = _image_of(Path(source))
        if image is not None:
            digest.update(image.read_bytes())
    except OSError:
        return None
    digest.update(repr((_CACHE_VERSION, cfg.field_distance, cfg.wall_radius)).encode())
    digest.update(occupancy_map.cells.tobytes())
    return digest.hexdigest()


def _image_of(yaml_path: Path) -> Path | None:
    """The image a map yaml names (None where it names none)."""
    for line in yaml_path.read_text(encoding="utf-8", errors="replace").splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "image":
            image = Path(value.strip().strip("'\""))
            return image if image.is_absolute() else yaml_path.parent / image
    return None


def _read_cache(path: Path, key: str) -> dict[str, NDArray] | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            return {name: data[name] for name in data.files if name != "key"}
    except (OSError, KeyError, ValueError):
        return None


def _write_cache(path: Path, key: str, arrays: dict[str, NDArray]) -> None:
    """Atomically; any failure (a read-only folder, a full disk) leaves no file and no error."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
    except OSError:
        return
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, key=np.array(key), **arrays)  # type: ignore[arg-type]
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def field_of(occupancy_map: OccupancyMap, cfg: LocalizationConfig) -> MapField:
    """The :class:`MapField` of a map, read from its cache beside the map's file where that
    holds this map's (and written there after computing it, where the folder allows)."""
    key = _cache_key(occupancy_map, cfg)
    arrays = None
    cache = None
    if key is not None and occupancy_map.source is not None:
        cache = Path(str(occupancy_map.source) + CACHE_SUFFIX)
        arrays = _read_cache(cache, key) if cache.is_file() else None
    if arrays is None:
        arrays = compute_field(occupancy_map, cfg)
        if cache is not None and key is not None:
            _write_cache(cache, key, arrays)
    res = float(occupancy_map.resolution)
    walls = WallField(
        np.ascontiguousarray(arrays["distance"], dtype=np.float64),
        np.ascontiguousarray(arrays["nearest"], dtype=np.int64),
        np.ascontiguousarray(arrays["wall"], dtype=np.float64).reshape(-1, 4),
        np.array([res, float(cfg.field_distance)]),
    )
    return MapField(
        occupancy_map,
        walls,
        np.asarray(arrays["free"], dtype=np.bool_),
        np.asarray(arrays["free_distance"], dtype=np.float64),
    )
