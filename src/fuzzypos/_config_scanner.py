"""The configuration section of the scanner's readings: which values mean "no return". Part of
:mod:`fuzzypos.config`, which assembles every section into ``Config``."""

from __future__ import annotations

from dataclasses import dataclass

from ._config_schema import _field, section

Band = tuple[float, float]


@dataclass(frozen=True)
@section("scanner")
class ScannerConfig:
    """What a scanner's readings mean beyond :class:`~fuzzypos.scan.LaserScan`'s own validity.

    ``no_return_bands``: ``[low, high]`` pairs in metres, inclusive (``[v, v]`` is the value
    ``v`` alone; an empty list drops nothing). A reading inside one of them is invalid, like
    one at or above ``range_max``; see :func:`fuzzypos.scan.no_return_mask`.
    """

    no_return_bands: tuple[Band, ...] = _field(
        ((81.83, 81.91),),
        "SICK LMS scanners in cm mode report a failed measurement (no echo, dazzle, overflow) "
        "as the codes 8183-8191 cm instead of a distance; a log whose maximum range lies "
        "above them (FLASER max_range 81.90 m) would otherwise take them for walls",
        unit="m",
        ge=0.0,
    )
