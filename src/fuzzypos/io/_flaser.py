"""FLASER beam geometry, shared by the CARMEN reader and writer: FLASER lines carry no angles,
so both sides must agree on a field of view and a convention (:func:`carmen_beam_geometry`)."""

from __future__ import annotations

import math

from ..errors import Argument, ArgumentError, Words

__all__ = [
    "CONVENTIONS",
    "GEOMETRY_TOL",
    "RANGE_DECIMALS",
    "carmen_beam_geometry",
    "check_convention",
    "check_fov",
]

#: the beam-angle conventions FLASER readers and writers understand (see :mod:`.carmen`)
CONVENTIONS = ("auto", "resolution", "span")

#: tolerance (radians) when checking that a scan's geometry fits the FLASER convention
GEOMETRY_TOL = 1e-7

#: decimals of the ranges written to a CARMEN log (0.1 mm; poses and stamps get repr)
RANGE_DECIMALS = 4

_FOV = Argument("field_of_view_deg")


def carmen_beam_geometry(
    n: int, field_of_view_deg: float = 180.0, convention: str = "auto"
) -> tuple[float, float]:
    """``(angle_min, angle_increment)`` in radians of an ``n``-beam FLASER scan.

    Beams start at ``-fov/2`` and go counter-clockwise. ``"resolution"``: increment
    ``fov/n``; ``"span"``: ``fov/(n-1)`` (the last beam at ``+fov/2``); ``"auto"``: the
    first for even ``n`` (180, 360), the second for odd ``n`` (181, 361).
    """
    fov = check_fov(field_of_view_deg)
    check_convention(convention)
    if isinstance(n, bool) or int(n) != n or n < 2:
        raise ValueError(f"a FLASER scan needs an integer beam count >= 2, got {n!r}")
    n = int(n)
    if convention == "auto":
        convention = "resolution" if n % 2 == 0 else "span"
    fov_rad = math.radians(fov)
    inc = fov_rad / n if convention == "resolution" else fov_rad / (n - 1)
    return -fov_rad / 2.0, inc


def check_fov(field_of_view_deg: float) -> float:
    """``field_of_view_deg`` as a float in (0, 360]; :class:`ArgumentError` (a ``ValueError``)
    otherwise."""
    try:
        fov = float(field_of_view_deg)
    except (TypeError, ValueError):
        raise ArgumentError(Words(_FOV, f" must be a number, got {field_of_view_deg!r}")) from None
    if not 0.0 < fov <= 360.0:
        raise ArgumentError(Words(_FOV, f" must be in (0, 360], got {fov}"))
    return fov


def check_convention(convention: str) -> None:
    """:class:`ArgumentError` (a ``ValueError``) unless ``convention`` is one of
    :data:`CONVENTIONS`."""
    if convention not in CONVENTIONS:
        raise ArgumentError(
            Words(Argument("convention"), f" must be one of {CONVENTIONS}, got {convention!r}")
        )
