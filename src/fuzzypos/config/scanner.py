"""The configuration section of the scanner's readings: which values mean "no return". Part of
:mod:`fuzzypos.config`, which assembles every section into ``Config``."""

from __future__ import annotations

from dataclasses import dataclass

from .schema import _field, section

Band = tuple[float, float]


@dataclass(frozen=True)
@section("scanner")
class ScannerConfig:
    """What a scanner's readings mean beyond :class:`~fuzzypos.scan.LaserScan`'s own validity.

    ``no_return_bands``: ``[low, high]`` pairs in metres, inclusive (``[v, v]`` is the value
    ``v`` alone; an empty list drops nothing). A reading inside one of them is invalid, like
    one at or above ``range_max``; see :func:`fuzzypos.scan.no_return_mask`.

    ``find_no_return_values`` and the ``find_*`` thresholds: a first pass over the log finds
    the values its scanner uses as "no return" codes, which the run adds to the bands
    (:mod:`fuzzypos.io.no_returns`: criteria (a)-(d) there).
    """

    no_return_bands: tuple[Band, ...] = _field(
        ((81.83, 81.91),),
        "SICK LMS scanners in cm mode report a failed measurement (no echo, dazzle, overflow) "
        "as the codes 8183-8191 cm instead of a distance; a log whose maximum range lies "
        "above them (FLASER max_range 81.90 m) would otherwise take them for walls",
        unit="m",
        ge=0.0,
    )
    find_no_return_values: bool = _field(
        True,
        'scanners report "nothing there" as codes nobody configured (held-back logs: 50.0 m '
        "and 51.14 m below the 51.16 m maximum inferred for them, thousands of readings taken "
        "for walls); a first pass over the log finds them from the readings alone",
    )
    find_min_readings: int = _field(
        200,
        "(a) a code is repeated exactly in hundreds of readings (held-back logs: 578 to 3,020 "
        "per code); an ordinary value that repeats as often in a long log is no spike (c)",
        ge=2,
    )
    find_min_fraction: float = _field(
        0.003,
        "(a) or, in a log too short for hundreds, in 0.3 % of its readings: a scanner that "
        "misses a beam or two per scan fills more than that with its code",
        ge=0.0,
        le=1.0,
    )
    find_floor_readings: int = _field(
        20,
        "(a) but never in fewer than 20: in a few scans a far wall's exact value repeats too, "
        "and so few readings cannot show a spike",
        ge=2,
    )
    find_top_fraction: float = _field(
        0.01,
        "(b) a code lies at the top of what the scanner reports: at most 1 % of the log's other "
        "readings (those of other codes left aside) lie above it, i.e. above their 99th "
        "percentile; a wall that repeats a value is seen nearer than the far readings",
        ge=0.0,
        le=1.0,
    )
    find_window: float = _field(
        0.05,
        "(c) the neighbourhood a code stands out of, ±5 cm: several times a scanner's noise and "
        "resolution, so a real surface's readings spread over it",
        unit="m",
        gt=0.0,
    )
    find_spike_ratio: float = _field(
        1.0,
        "(c) a code holds at least as many readings as all the other values within the window "
        "together (10 of them at 1 cm resolution, 100 at 1 mm): an ordinary range holds a few "
        "per cent of its neighbourhood's",
        gt=0.0,
    )
    find_moving_share: float = _field(
        0.5,
        "(d) a code is read while the robot moves as well as while it stands: the share of its "
        "readings from scans after the odometry changed is at least half the log's; a wall "
        "seen while standing still repeats its value at one pose only",
        ge=0.0,
        le=1.0,
    )
