"""Simulated runs of the kinds of real log the estimator is checked on, with known truth.

:func:`sick_outdoor_run` mimics a held-back CARMEN log (``ROBOTLASER1``): a SICK scanner in
interlaced mode (:func:`sick_interlaced_scanner`) on a robot driving slowly through a large yard
(:func:`outdoor_yard`), whose wheel odometry is precise but under-reads rotation by 1%
(:func:`sick_outdoor_slip`). Its parts can be used on their own.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..geometry import Pose2D
from .robot import CommandedPath, SimulatedRun, SlipModel, simulate_run
from .scanner import ScannerModel
from .world import FloatArray, World
from .worlds import box_polygon, circle_polygon

__all__ = [
    "SICK_NO_RETURN",
    "SICK_RANGE_MAX",
    "SICK_OUTDOOR_SPEED",
    "outdoor_yard",
    "sick_interlaced_scanner",
    "sick_outdoor_slip",
    "sick_outdoor_path",
    "sick_outdoor_run",
]

#: the SICK's maximum range in the log (ROBOTLASER1 ``max_range``), m
SICK_RANGE_MAX = 81.9
#: the SICK's "no return" code: the reading of a beam with no echo, m (below the maximum
#: range, so a scan sees it as a valid reading)
SICK_NO_RETURN = 81.83
#: the robot's speed, m/s: 0.25 m between scans at 1.6 Hz
SICK_OUTDOOR_SPEED = 0.4

#: the yard's outline, building fronts with recesses (anticlockwise, m)
_YARD = (
    (-48.0, -32.0),
    (-20.0, -32.0),
    (-20.0, -28.0),
    (5.0, -28.0),
    (5.0, -32.0),
    (48.0, -32.0),
    (48.0, -5.0),
    (44.0, -5.0),
    (44.0, 8.0),
    (48.0, 8.0),
    (48.0, 34.0),
    (15.0, 34.0),
    (15.0, 30.0),
    (-10.0, 30.0),
    (-10.0, 34.0),
    (-48.0, 34.0),
)
#: free-standing buildings: (cx, cy, length, width, theta_deg)
_BUILDINGS = (
    (-28.0, 14.0, 10.0, 7.0, 0.0),
    (26.0, -16.0, 12.0, 6.0, 15.0),
    (-22.0, -14.0, 4.0, 3.0, -20.0),
    (30.0, 18.0, 6.0, 4.0, 30.0),
)
#: posts: ("round", cx, cy, radius) or ("square", cx, cy, side)
_POSTS = (
    ("square", -12.0, -14.0, 0.3),
    ("round", -4.0, -14.0, 0.15),
    ("square", 4.0, -14.0, 0.3),
    ("round", 12.0, -14.0, 0.15),
    ("square", -6.0, 15.0, 0.3),
    ("round", 2.0, 15.0, 0.15),
    ("square", 10.0, 15.0, 0.3),
    ("square", -26.0, 0.0, 0.4),
    ("round", 26.0, 2.0, 0.2),
)


def outdoor_yard() -> World:
    """A 96 m x 66 m yard (or a large hall) of sparse, far structure round the origin.

    - The yard's edge: building fronts at ``x = ±48`` and ``y = -32, +34``, each with a recess
      or a bay 4 m deep (so the edge has corners); closed, so every beam hits something within
      the SICK's 81.9 m (the far corners are 59 m from the middle, at most 69 m from the path).
    - Four free-standing buildings (4-12 m long, three of them turned) 15-30 m out, and nine
      posts (lamp posts, 0.3-0.4 m square or round): rows at ``y = -14`` and ``y = 15``,
      10-11 m off the path of :func:`sick_outdoor_path` (which keeps to ``|x| < 12,
      |y| < 4.6``), and two 14 m off its ends.

    So from the path everything is at least 9.5 m away and most of what the laser sees 20-60 m
    (median 36 m): a 1° beam spacing puts the points 0.2-1 m apart. Deterministic.
    """
    polys: list[FloatArray] = [np.array(_YARD, dtype=float)]
    for cx, cy, length, width, theta_deg in _BUILDINGS:
        polys.append(box_polygon(cx, cy, length, width, math.radians(theta_deg)))
    for kind, cx, cy, size in _POSTS:
        if kind == "round":
            polys.append(circle_polygon(cx, cy, size))
        else:
            polys.append(box_polygon(cx, cy, size, size))
    return World.from_polygons(polys, name="outdoor_yard")


def sick_interlaced_scanner(**overrides: Any) -> ScannerModel:
    """A SICK LMS in interlaced mode as in the held-back log; ``overrides`` replace fields.

    - 1° between beams, the start angle cycling through -90°, -89.75°, -89.5°, -89.25°
      (``start_angle_offsets_deg`` 0, 0.25, 0.5, 0.75) with 181 beams at the first (-90°..+90°)
      and 180 at the others (``beam_counts``): four scans together sample every 0.25°.
    - ``range_max`` 81.9 m; a beam with no echo reads the no-return code 81.83 m
      (``no_return_value``), and 12% of the beams return nothing (``dropout_probability``:
      outdoors, dark or wet surfaces, glass, beams grazing the ground); the yard is closed, so
      these are all the no-returns. ``range_min`` 0.
    - Range noise ``0.01 m + 0.0005 m/m`` (1 cm near, 3.5 cm at 50 m) plus up to 2 cm at
      grazing incidence; 0.2% spurious short returns.
    - 1.6 scans a second; mounted 0.22 m ahead of the robot's centre (``sensor_pose``).
    """
    values: dict[str, Any] = {
        "n_beams": 180,
        "field_of_view_deg": 180.0,
        "angle_min_deg": -90.0,
        "start_angle_offsets_deg": (0.0, 0.25, 0.5, 0.75),
        "beam_counts": (181, 180, 180, 180),
        "range_max": SICK_RANGE_MAX,
        "range_min": 0.0,
        "no_return_value": SICK_NO_RETURN,
        "range_noise_std": 0.01,
        "range_noise_per_metre": 0.0005,
        "incidence_noise": 0.02,
        "dropout_probability": 0.12,
        "spurious_probability": 0.002,
        "rate_hz": 1.6,
        "sensor_pose": Pose2D(0.22, 0.0, 0.0),
    }
    values.update(overrides)
    return ScannerModel(**values)


def sick_outdoor_slip(rotation_under_read: float = 0.01, **overrides: Any) -> SlipModel:
    """Precise wheel odometry that under-reads rotation: it reports ``1 − rotation_under_read``
    of every true turn (the robot turns ``1 / 0.99`` of what its wheels say: ``angular =
    1 − 1/(1 − rotation_under_read)``, negative). No longitudinal slip, no skid; encoder noise
    ``translation_noise`` 0.003 √m (3 mm after 1 m) and ``rotation_noise`` 0.003 √rad (0.17°
    after a full turn), so over a few seconds it is better than a scan matcher, while over a
    run its heading drifts by 1% of the angle turned (3.6° a lap). ``overrides`` replace
    fields."""
    values: dict[str, Any] = {
        "radial_gain": 0.0,
        "longitudinal": 0.0,
        "angular": 1.0 - 1.0 / (1.0 - float(rotation_under_read)),
        "translation_noise": 0.003,
        "rotation_noise": 0.003,
    }
    values.update(overrides)
    return SlipModel(**values)


def sick_outdoor_path(speed: float = SICK_OUTDOOR_SPEED) -> CommandedPath:
    """A 78 m drive at ``speed`` (0.4 m/s, 194 s): a stadium lap (16 m straights along
    ``y = ∓4``, 180° turns of radius 4 m round ``(±8, 0)``, anticlockwise) from ``(-8, -4)``
    heading +x, then 6 m on along ``y = -4``, an S-bend (90° left then 90° right, radius 4 m)
    and 2 m straight, ending near ``(6, 4)`` heading +x. Turns are arcs (3.6° between scans at
    1.6 Hz), not turns on the spot."""
    v = float(speed)
    r = 4.0
    half = math.pi * r / v  # seconds for a 180° arc of radius r
    quarter = half / 2.0
    segments = [
        [16.0 / v, v, 0.0],
        [half, v, v / r],
        [16.0 / v, v, 0.0],
        [half, v, v / r],
        [6.0 / v, v, 0.0],
        [quarter, v, v / r],
        [quarter, v, -v / r],
        [2.0 / v, v, 0.0],
    ]
    return CommandedPath(
        np.array(segments), Pose2D(-8.0, -4.0, 0.0), name="sick_outdoor(stadium + S-bend)"
    )


def sick_outdoor_run(
    seed: int = 0,
    *,
    duration: float | None = None,
    scanner: ScannerModel | None = None,
    slip: SlipModel | None = None,
    with_scans: bool = True,
) -> SimulatedRun:
    """A simulated run of the held-back real log's kind (CARMEN ``ROBOTLASER1``, a SICK LMS
    in interlaced mode, outdoors or in a large hall).

    What it mimics: :func:`sick_interlaced_scanner` (start angles cycling 0.25° apart, 181/180
    beams 1° apart, 1.6 Hz, 81.9 m range, 12% no-returns read as the code 81.83 m, the laser
    0.22 m ahead of the base) on a robot driving :func:`sick_outdoor_path` (0.4 m/s, 0.25 m
    between scans, arcs of radius 4 m) through :func:`outdoor_yard` (structure 10-50 m away),
    with :func:`sick_outdoor_slip`'s odometry (precise, under-reading rotation by 1%). 311
    scans over 194 s (``duration`` cuts it short); ``scanner`` and ``slip`` replace the
    defaults. The same ``seed`` gives a bitwise identical run.
    """
    return simulate_run(
        outdoor_yard(),
        sick_outdoor_path(),
        sick_interlaced_scanner() if scanner is None else scanner,
        sick_outdoor_slip() if slip is None else slip,
        seed,
        duration=duration,
        with_scans=with_scans,
    )
