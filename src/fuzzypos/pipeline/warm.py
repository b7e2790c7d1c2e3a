"""Compile (or load from numba's disk cache) every compiled kernel now rather than on the
first scans that need them: a short drive through a synthetic room, a wide search, the point
features. The first call of a fresh install compiles (seconds); later processes load the
machine code from the cache (``__pycache__`` beside the kernels)."""

from __future__ import annotations

import contextlib
import importlib
import math
import pkgutil
import time
from collections.abc import Callable
from contextlib import AbstractContextManager

import numpy as np
from numpy.typing import NDArray

from .._kernels import compiled
from ..config import Config
from ..features import extract_features
from ..geometry import Pose2D, compose
from ..matching import search_start, surface_points
from ..scan import LaserScan
from .positioner import Positioner

__all__ = ["compile_kernels", "kernels_cold", "warm_up"]

FloatArray = NDArray[np.float64]

#: the synthetic room's walls and a pillar, segments (x0, y0, x1, y1) in metres
_WALLS = np.array(
    [
        [-4.0, -3.0, 4.0, -3.0],
        [4.0, -3.0, 4.0, 3.0],
        [4.0, 3.0, -4.0, 3.0],
        [-4.0, 3.0, -4.0, -3.0],
        [1.0, 0.5, 2.0, 0.5],
        [2.0, 0.5, 2.0, 1.5],
        [2.0, 1.5, 1.0, 1.5],
        [1.0, 1.5, 1.0, 0.5],
    ]
)


def _scan(pose: FloatArray, beams: int, stamp: float) -> LaserScan:
    """A 180° scan of the synthetic room from ``pose`` (ray against every wall)."""
    inc = math.pi / beams
    angles = pose[2] - 0.5 * math.pi + inc * np.arange(beams)
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x0, y0, x1, y1 = (_WALLS[:, k][None, :] for k in range(4))
    ex, ey = x1 - x0, y1 - y0
    den = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((x0 - pose[0]) * ey - (y0 - pose[1]) * ex) / den  # along the ray
        s = ((x0 - pose[0]) * dy - (y0 - pose[1]) * dx) / den  # along the wall
    hit = (t > 0.0) & (s >= 0.0) & (s <= 1.0) & np.isfinite(t)
    ranges = np.where(hit, t, np.inf).min(axis=1)
    ranges = ranges * (1.0 + 0.001 * np.sin(7.0 * np.arange(beams)))  # not exactly straight
    return LaserScan(ranges, -0.5 * math.pi, inc, 0.0, 20.0, stamp)


#: the kernel modules of localisation in a map (``fuzzypos.localization``), compiled only for it
MAP_KERNELS = ("localize", "agreement")


def warm_up(config: Config | None = None, *, in_map: bool = False) -> float:
    """Run every compiled kernel of positioning once (each is compiled, or loaded from the disk
    cache, on its first call), and with ``in_map`` those of localisation in a map
    (:data:`MAP_KERNELS`) too; returns the seconds it took."""
    t0 = time.perf_counter()
    cfg = config if config is not None else Config()
    step = np.array([0.08, 0.0, 0.02])
    # the drive twice: through the common path's one compiled call, and through the staged
    # calls it fuses (those the rarer paths make: after an odometry jump, where a stage hands
    # over; a kernel called from Python is compiled apart from its call inside another)
    for fused in (False, True):
        positioner = Positioner(cfg, fused=fused)
        pose = np.array([-2.0, -1.0, 0.1])
        scans = []
        for k in range(8):
            scan = _scan(pose, 180, 0.1 * k)
            scans.append(scan)
            positioner.update(scan, Pose2D.from_array(pose))
            pose = compose(pose, step)
        # a scan without odometry: the prior the last increment, its covariance the broad one
        positioner.update(_scan(pose, 180, 0.8), None)
    f = extract_features(scans[0], cfg)
    _ = f.points_of_interest
    surface = surface_points(f.points, f.ranges, f.uncertainty, cfg.refinement)
    search_start(
        surface, f.points, np.zeros(3), cfg.search, half_width=0.1, translation_half_width=0.2
    )
    # the single fit from a search's start (``Relocaliser``), which the drive does not reach
    points = positioner.refiner.points(f, scans[0].angle_increment)
    if points is not None:
        zero = np.zeros(3)
        positioner.refiner.fit(
            surface, points, zero, zero, zero, max_distance=cfg.search.jump_distance,
            weak_prior=True,
        )  # fmt: skip
    from .._kernels import f64

    if compiled():  # the CARMEN writer's and reader's ranges (fuzzypos.io.carmen*)
        from .._kernels.pipeline import move_surfaces
        from .._kernels.text import fixed_text, parse_decimals

        _ok, text = fixed_text(scans[0].ranges, 10_000, 4, 5)
        # (as the reader hands it a line: a read-only view of its bytes)
        parse_decimals(np.frombuffer(text.tobytes(), dtype=np.uint8), scans[0].ranges.shape[0])
        # a local map of several keyframes (the short drive renews the keyframe only once)
        moves, ends = np.array([(0.0, 0.0, 1.0, 0.0)]), np.array([len(surface)], dtype=np.int64)
        move_surfaces(f64(surface.xy), f64(surface.normal), moves, ends)
        # the refinement's priors from the learned noise (once it is trusted)
        noise = positioner.odometry_noise
        positioner.uncertainty.prior_information(
            np.array([0.1, 0.0, 0.02]), step, noise.covariance(step)
        )
    if in_map and compiled():  # localisation in a map (fuzzypos.localization)
        from .._kernels.agreement import warm as warm_agreement
        from .._kernels.localize import warm as warm_localization

        warm_localization()
        warm_agreement()
    return time.perf_counter() - t0


def kernels_cold(*, in_map: bool = False) -> bool:
    """Whether :func:`warm_up` will compile rather than load (quick: numba's cache indexes
    read, nothing compiled): where some kernel module has no kernel whose cache index loads.
    numba's index is stale, and reads as empty, where its module's file (size, time), the
    kernels' sources (:func:`~fuzzypos._kernels._jit.sources_stamp`) or numba's version
    changed; a kernel only ever called from another kernel keeps no index of its own, but
    each module has one :func:`warm_up` calls from Python (:data:`MAP_KERNELS`' only with
    ``in_map``). False where the compiled kernels are off, or numba's cache cannot be read so
    (not known to be cold)."""
    if not compiled():
        return False
    from .. import _kernels

    try:
        for info in pkgutil.iter_modules(_kernels.__path__):
            if info.name in MAP_KERNELS and not in_map:
                continue
            module = importlib.import_module(f"{_kernels.__name__}.{info.name}")
            indexes = [
                value._cache._cache_file
                for value in vars(module).values()
                if getattr(getattr(value, "py_func", None), "__module__", "") == module.__name__
            ]
            if indexes and not any(index._load_index() for index in indexes):
                return True
    except (AttributeError, OSError):  # another numba's cache, or none to read
        return False
    return False


#: the seconds of this process's :func:`compile_kernels`, without and with ``in_map``
_compiled_in: dict[bool, float] = {}


def compile_kernels(
    config: Config | None = None,
    announce: Callable[[], AbstractContextManager[object]] | None = None,
    *,
    in_map: bool = False,
) -> float:
    """Compile (or load) every kernel of positioning (with ``in_map``, of localisation in a map
    too) once per process (:func:`warm_up`), inside ``announce()`` where the cache is cold
    (:func:`kernels_cold`: its caller says why this takes a while); returns the seconds it
    took, 0 after the first call and where the compiled kernels are off."""
    if in_map in _compiled_in or not compiled():
        return 0.0
    t0 = time.perf_counter()
    cold = announce is not None and kernels_cold(in_map=in_map)
    with announce() if cold and announce is not None else contextlib.nullcontext():
        warm_up(config, in_map=in_map)
    _compiled_in[in_map] = time.perf_counter() - t0
    return _compiled_in[in_map]
