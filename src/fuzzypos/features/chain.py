"""What the compiled feature chain (``_kernels.front.scan_features``) reads of a scan and a
config (part of :mod:`fuzzypos.features`): its settings in one array and its arguments."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .._kernels import packing
from ..config import Config, FuzzyConfig, LineConfig, same_as_last_call
from ..fuzzy import RuleBases
from ..scan import LaserScan
from .segmentation import _band_bounds_of, _front_params

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: m: floor of a line's residual spread, so noise-free lines keep finite weights
MIN_LINE_NOISE = 0.001

#: :func:`chain_inputs`: ``_kernels.front.scan_features``' arguments (the ranges, the beams'
#: directions, the valid mask, the angle increment, the sensor's pose on the robot as three
#: numbers, whether the beams close a turn, the config's settings)
ChainInputs = tuple[
    FloatArray, FloatArray, BoolArray, float, float, float, float, bool, FloatArray
]  # fmt: skip
#: ``_kernels.front.scan_features``' values after whether it is done: the points' and the
#: lines' distance scales, the sizes and the packed floats, integers and masks
ChainOutputs = tuple[
    float, float, tuple[int, int, int, int, int], FloatArray, IntArray, BoolArray
]  # fmt: skip


def chain_inputs(scan: LaserScan, config: Config, bases: RuleBases) -> ChainInputs | None:
    """What the compiled chain reads of ``scan`` and the config (``bases``: its rule bases);
    None where a rule base is off the interpolation's path (then the
    staged chain runs). The positioner hands them to its one compiled call of a scan's
    features, match, refinement and assessment (``_kernels.step``)."""
    settings = chain_settings(config, bases)
    if settings is None:
        return None
    sp = scan.sensor_pose
    directions, closed = packing.scanner(scan)
    return (
        scan.ranges, directions, scan.valid, scan.angle_increment, sp.x, sp.y, sp.theta, closed,
        settings,
    )  # fmt: skip


@same_as_last_call
def chain_settings(cfg: Config, bases: RuleBases) -> FloatArray | None:
    """``_kernels.front.scan_features``' settings of a config and its rule bases in one array
    (``packing.chain_settings``; read-only): the no-return bands' bounds, the front's and the
    lines' params, the sine of the least angle lines are joined at, and the point and line
    rule bases' tables; None where a rule base is off the interpolation's path."""
    pb, lb = bases.points, bases.lines
    if pb._grids is None or lb._grids is None:
        return None
    lo, hi = _band_bounds_of(cfg.scanner)
    front = _front_params(cfg.segmentation, cfg.angular_points, cfg.fuzzy, cfg.filtering, cfg.lines)
    return packing.chain_settings(
        lo, hi, front, line_params(cfg.lines, cfg.fuzzy),
        math.sin(cfg.virtual_points.min_intersection_angle),
        (*pb._grids, pb._table, pb._centre_lo, pb._centre_hi),
        (*lb._grids, lb._table, lb._centre_lo, lb._centre_hi),
    )  # fmt: skip


@same_as_last_call
@lru_cache(maxsize=16)
def line_params(lines: LineConfig, fz: FuzzyConfig) -> FloatArray:
    """``_kernels.front.fit_lines``' params of a config's sections (cached; not to be written
    to)."""
    structure = fz.distance_scale != "fixed" and fz.line_distance_scale == "structure"
    return np.array([
        lines.min_points, lines.min_length, MIN_LINE_NOISE, float(structure),
        fz.distance_scale_reference, fz.distance_scale_quantile,
    ], dtype=np.float64)  # fmt: skip
