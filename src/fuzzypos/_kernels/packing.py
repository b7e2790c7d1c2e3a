"""How :func:`~fuzzypos._kernels.front.scan_features` hands its arrays to Python and how
``fuzzypos.features`` takes them apart, in plain Python (no numba: ``fuzzypos.features``
imports this on import). Each array a compiled call returns is boxed by numba, so the
call packs its three dozen end to end in three (floats, integers,
masks; :data:`LAYOUT` says where each sits) and the features are views of them, those the
positioner does not read per scan taken out on first use (:class:`Unpacks`). Also the
scanner's beam directions, computed once per scanner (:func:`scanner`)."""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from functools import lru_cache
from types import ModuleType
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from .front import ChainSizes

__all__ = [
    "LAYOUT", "Packed", "Unpacks", "chain_settings", "front", "lines_first", "new", "scanner",
    "unpacked",
]  # fmt: skip

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


class Bearings(Protocol):
    """What :func:`scanner` reads of a scan (``fuzzypos.scan.LaserScan``)."""

    @property
    def angle_min(self) -> float: ...
    @property
    def angle_increment(self) -> float: ...
    @property
    def ranges(self) -> FloatArray: ...
    @property
    def angles(self) -> FloatArray: ...
    @property
    def is_full_circle(self) -> bool: ...


class Packed:
    """:func:`~fuzzypos._kernels.front.scan_features`' sizes (:data:`~.front.ChainSizes`)
    and its three packed arrays (floats, integers, masks)."""

    __slots__ = ("buffers", "sizes")

    def __init__(self, sizes: ChainSizes, fl: FloatArray, it: IntArray, bl: BoolArray) -> None:
        self.sizes = sizes
        self.buffers: tuple[NDArray[Any], NDArray[Any], NDArray[Any]] = (fl, it, bl)

    def view(self, where: _Where) -> NDArray[Any]:
        """The array at ``where`` (:data:`LAYOUT`), a view of its buffer."""
        which, first, length, columns = where
        start, size = _dot(first, self.sizes), _dot(length, self.sizes)
        out = self.buffers[which][start : start + columns * size]
        return out.reshape(size, 2) if columns == 2 else out


#: where an array sits in :class:`Packed`: the buffer (0 floats, 1 integers, 2 masks), its
#: first element and its rows as sums of the sizes times these coefficients (valid points,
#: kept points, lines, angular points, joined ones), and its columns
_Where = tuple[int, tuple[int, int, int, int, int], tuple[int, int, int, int, int], int]

#: the rows of an array of each size
_N, _M, _L = (1, 0, 0, 0, 0), (0, 1, 0, 0, 0), (0, 0, 1, 0, 0)
_C, _J = (0, 0, 0, 1, 0), (0, 0, 0, 0, 1)


def _dot(a: tuple[int, ...], b: tuple[int, ...]) -> int:
    """Σ a_i · b_i of two 5-tuples."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4]


#: the arrays of each class (``fuzzypos.features``' ``Features``, ``Lines`` and corners'
#: context) in :func:`~fuzzypos._kernels.front.scan_features`' packing, in its order
LAYOUT: dict[str, dict[str, _Where]] = {
    "Features": {
        "points": (0, (0, 0, 0, 0, 0), _N, 2),
        "ranges": (0, (2, 0, 0, 0, 0), _N, 1),
        "detection_angle": (0, (3, 0, 0, 0, 0), _N, 1),
        "uncertainty": (0, (4, 0, 0, 0, 0), _N, 1),
        "beam_index": (1, (0, 0, 0, 0, 0), _N, 1),
        "kept_index": (1, (1, 0, 0, 0, 0), _M, 1),
        "cluster": (1, (1, 1, 0, 0, 0), _M, 1),
        "segment": (1, (1, 2, 0, 0, 0), _M, 1),
        "kept": (2, (0, 0, 0, 0, 0), _N, 1),
        "is_break_point": (2, (1, 0, 0, 0, 0), _M, 1),
        "is_field_of_view_edge": (2, (1, 1, 0, 0, 0), _M, 1),
        "is_angular_point": (2, (1, 2, 0, 0, 0), _M, 1),
    },
    "Lines": {
        "normal": (0, (5, 4, 0, 0, 0), _L, 2),
        "distance": (0, (5, 4, 2, 0, 0), _L, 1),
        "start": (0, (5, 4, 3, 0, 0), _L, 2),
        "end": (0, (5, 4, 5, 0, 0), _L, 2),
        "centre": (0, (5, 4, 7, 0, 0), _L, 2),
        "sigma": (0, (5, 4, 9, 0, 0), _L, 1),
        "delta": (0, (5, 4, 10, 0, 0), _L, 1),
        "uncertainty": (0, (5, 4, 11, 0, 0), _L, 1),
        "angle_variance": (0, (5, 4, 12, 0, 0), _L, 1),
        "distance_variance": (0, (5, 4, 13, 0, 0), _L, 1),
        "n_points": (1, (1, 3, 0, 0, 0), _L, 1),
        "segment": (1, (1, 3, 1, 0, 0), _L, 1),
        "cluster": (1, (1, 3, 2, 0, 0), _L, 1),
    },
    "_CornerContext": {
        "kept_points": (0, (5, 0, 0, 0, 0), _M, 2),
        "kept_uncertainty": (0, (5, 2, 0, 0, 0), _M, 1),
        "kept_ranges": (0, (5, 3, 0, 0, 0), _M, 1),
        "corner_xy": (0, (5, 4, 15, 0, 0), _C, 2),
        "corner_dv": (0, (5, 4, 15, 2, 0), _J, 1),
        "corner_index": (1, (1, 3, 3, 0, 0), _C, 1),
        "seg_before": (1, (1, 3, 3, 1, 0), _C, 1),
        "seg_after": (1, (1, 3, 3, 2, 0), _C, 1),
        "corner_a": (1, (1, 3, 3, 3, 0), _J, 1),
        "corner_b": (1, (1, 3, 3, 3, 1), _J, 1),
        "break_mask": (2, (1, 3, 0, 0, 0), _M, 1),
        "joined": (2, (1, 4, 0, 0, 0), _C, 1),
    },
}


class Unpacks:
    """A dataclass whose fields the compiled chain may leave in its packed arrays (a
    ``_packed`` entry of the instance's dict, :class:`Packed`): each is taken out on first
    use and kept (the positioner reads few of them per scan).
    Instances made by their constructor have every field and never get here."""

    __slots__ = ()

    if not TYPE_CHECKING:  # (for mypy the fields are plain attributes)

        def __getattr__(self, name: str) -> Any:
            packed = self.__dict__.get("_packed")
            where = LAYOUT[type(self).__name__].get(name) if packed is not None else None
            if where is None:
                raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
            value = packed.view(where)
            self.__dict__[name] = value
            return value


#: a rule base's tables as the compiled chain reads them: the grids of its two inputs, its
#: table and the bounds its output is clamped to (``fuzzy.RuleBase``)
_Tables = tuple[FloatArray, FloatArray, FloatArray, float, float]


def chain_settings(
    band_lo: FloatArray, band_hi: FloatArray, front_params: FloatArray,
    line_params: FloatArray, min_sine: float, point_tables: _Tables, line_tables: _Tables,
) -> FloatArray:  # fmt: skip
    """:func:`~fuzzypos._kernels.front.scan_features`' settings of a config in one float
    array (one argument for the compiled call, not one per setting):
    the sizes (the no-return bands, then each rule base's two grids and its table's rows and
    columns), the rule bases' bounds (points', lines'), the sine of the least angle lines are
    joined at, the front's and the lines' params, then the bands' bounds and each rule base's
    grids and table (``_kernels.front.settings_of`` takes them apart). Not to be written to
    (writable all the same: a read-only array is another type to numba, compiled anew)."""
    pg1, pg2, pt, plo, phi = point_tables
    lg1, lg2, lt, llo, lhi = line_tables
    sizes = [band_lo.shape[0], *pg1.shape, *pg2.shape, *pt.shape, *lg1.shape, *lg2.shape]
    sizes += [*lt.shape]
    head = [*sizes, plo, phi, llo, lhi, min_sine]
    parts = [np.array(head, dtype=np.float64), front_params, line_params, band_lo, band_hi]
    parts += [pg1, pg2, pt.ravel(), lg1, lg2, lt.ravel()]
    for part in parts:
        assert part.dtype == np.float64
    out: FloatArray = np.concatenate(parts)
    return out


@lru_cache(maxsize=1)
def front() -> ModuleType:
    """The compiled chain's kernels (``_kernels.front``), imported with numba on first use and
    kept."""
    return importlib.import_module("fuzzypos._kernels.front")


def scanner(scan: Bearings) -> tuple[FloatArray, bool]:
    """The (2, n) cosines and sines of the scan's bearings (``_kernels.front.beam_directions``
    of ``scan.angles``) and whether they close a turn (``scan.is_full_circle``), once per
    scanner geometry: the ones of an earlier call again where the bearings are that call's
    (the same ``angle_min``, to the sign of a zero, increment and count), of the last
    :data:`SCANNER_GEOMETRIES` (an interlaced scanner alternates between two)."""
    a0, inc, n = scan.angle_min, scan.angle_increment, scan.ranges.shape[0]
    sign = math.copysign(1.0, a0)
    for last in _last:
        if last[0] == a0 and last[1] == inc and last[2] == n and last[3] == sign:
            return last[4], last[5]
    table: FloatArray = front().beam_directions(scan.angles)
    table.setflags(write=False)
    closed = bool(scan.is_full_circle)
    _last.insert(0, (a0, inc, n, sign, table, closed))
    del _last[SCANNER_GEOMETRIES:]
    return table, closed


#: how many scanner geometries :func:`scanner` keeps (the latest first)
SCANNER_GEOMETRIES = 4
_last: list[tuple[float, float, int, float, FloatArray, bool]] = []


_T = TypeVar("_T")


def new(cls: type[_T], values: dict[str, Any]) -> _T:
    """An instance of the frozen dataclass ``cls`` with its fields' ``values`` put straight
    into its dict: what ``cls(**values)`` makes, without the frozen ``__init__``'s
    ``object.__setattr__`` per field; the fields left out an
    :class:`Unpacks` class takes from its ``_packed`` arrays."""
    obj = object.__new__(cls)
    obj.__dict__.update(values)
    return obj


@lru_cache(maxsize=1)
def lines_at() -> IntArray:
    """:func:`lines_first`'s coefficients of the sizes, as an array for a kernel that finds
    the lines in the packed floats itself (``_kernels.step.features_and_step``)."""
    return np.array(LAYOUT["Lines"]["normal"][1], dtype=np.int64)


def lines_first(sizes: ChainSizes) -> int:
    """Where the lines' floats begin in :func:`~fuzzypos._kernels.front.scan_features`' packed
    floats (:data:`LAYOUT`'s ``Lines``, after the points' ``5n + 4m``)."""
    return _dot(LAYOUT["Lines"]["normal"][1], sizes)


def unpacked(
    classes: tuple[type, type, type], empty_lines: Callable[[], Any], stamp: float,
    context: dict[str, Any], scale: float, line_scale: float, sizes: ChainSizes,
    fl: FloatArray, it: IntArray, bl: BoolArray,
) -> Any:  # fmt: skip
    """The ``Features`` (``classes``: it, ``Lines`` and the corners' context) of
    :func:`~fuzzypos._kernels.front.scan_features`' packed arrays, views of them where
    :data:`LAYOUT` has them (``context``: the corners' context's other fields, but its lines
    and scales; ``empty_lines()`` where there is no line), each taken out on first use
    (:class:`Unpacks`): the positioner's compiled call reads the packed arrays themselves.
    Put in here: the lines' variances (fields with a default, which an instance without them
    would read) and lengths, which come with them (``Lines.length`` would compute them)."""
    features_cls, lines_cls, context_cls = classes
    nl = sizes[2]
    packed = Packed(sizes, fl, it, bl)
    if nl == 0:
        lines = empty_lines()
    else:
        o = lines_first(sizes)
        lines = new(lines_cls, {
            "angle_variance": fl[o + 12 * nl : o + 13 * nl],
            "distance_variance": fl[o + 13 * nl : o + 14 * nl],
            "length": fl[o + 14 * nl : o + 15 * nl],
            "_packed": packed,
        })  # fmt: skip
    context["lines"] = lines
    context["distance_scale"], context["line_distance_scale"] = scale, line_scale
    context["_packed"] = packed
    return new(features_cls, {
        "stamp": stamp, "lines": lines, "_corners": new(context_cls, context), "_packed": packed,
    })  # fmt: skip
