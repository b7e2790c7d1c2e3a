"""Built-in worlds: :func:`gym`, :func:`office`, :func:`furnished_room`,
:func:`rectangular_room`, :func:`doorway_wall`, the polygon helpers :func:`box_polygon` and
:func:`circle_polygon`, and :func:`world_by_name` for the command line."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .world import FloatArray, SimError, World

__all__ = [
    "box_polygon",
    "circle_polygon",
    "rectangular_room",
    "furnished_room",
    "office",
    "doorway_wall",
    "gym",
    "WORLD_NAMES",
    "world_by_name",
]


def box_polygon(
    cx: float, cy: float, length: float, width: float, theta: float = 0.0
) -> FloatArray:
    """Vertices (CCW) of a ``length`` x ``width`` rectangle centred at ``(cx, cy)``, rotated
    by ``theta`` (``length`` along the rotated x axis)."""
    if not (length > 0 and width > 0):
        raise SimError(f"box sides must be positive, got {length} x {width}")
    hx, hy = length / 2.0, width / 2.0
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = math.cos(theta), math.sin(theta)
    vertices: FloatArray = local @ np.array([[c, s], [-s, c]]) + np.array([cx, cy])
    return vertices


def circle_polygon(cx: float, cy: float, radius: float, n: int = 16) -> FloatArray:
    """A regular ``n``-gon approximating a round pillar (16 sides bend by 22.5°, below the
    default 30° corner threshold, so a round pillar has no corners)."""
    if not radius > 0 or n < 3:
        raise SimError(f"a circle needs radius > 0 and n >= 3, got radius={radius}, n={n}")
    a = 2.0 * math.pi * np.arange(n) / n
    return np.column_stack([cx + radius * np.cos(a), cy + radius * np.sin(a)])


def rectangular_room(width: float = 8.0, height: float = 6.0) -> World:
    """An empty ``width`` (along x) by ``height`` (along y) room centred on the origin."""
    if not (width > 0 and height > 0):
        raise SimError(f"room sides must be positive, got {width} x {height}")
    return World.from_polygons([box_polygon(0.0, 0.0, width, height)], name="rectangular_room")


#: furnished_room: room half-sizes, the free central area's half-sizes, and the fixed layout.
_ROOM_HALF = (5.0, 4.0)
_FREE_HALF = (2.0, 1.5)
#: (cx, cy, length, width, theta_deg) of the pieces of furniture in the seed-0 layout
_FURNITURE = (
    (1.8, 3.0, 1.2, 0.8, 0.0),  # table
    (-4.2, 1.5, 1.0, 0.5, 90.0),  # cabinet along the left wall
    (4.0, -1.0, 0.6, 0.6, 30.0),  # box, rotated
    (-2.0, -3.2, 1.2, 0.6, -20.0),  # desk, rotated
    (-0.5, 3.1, 0.5, 0.8, 45.0),  # box, rotated
    (1.0, -3.2, 0.7, 0.5, 0.0),  # crate
)
#: pillars: ("round", cx, cy, radius) or ("square", cx, cy, side)
_PILLARS = (("round", -3.2, -0.6, 0.15), ("square", 3.0, 1.0, 0.3))


def _piece_fits(
    cx: float, cy: float, radius: float, placed: list[tuple[float, float, float]]
) -> bool:
    """Bounding-circle check: inside the room with a margin, clear of the free central area and
    of the pieces already placed."""
    margin = 0.25
    if abs(cx) + radius > _ROOM_HALF[0] - margin or abs(cy) + radius > _ROOM_HALF[1] - margin:
        return False
    gx = max(abs(cx) - _FREE_HALF[0], 0.0)
    gy = max(abs(cy) - _FREE_HALF[1], 0.0)
    if math.hypot(gx, gy) < radius + margin:
        return False
    return all(math.hypot(cx - x, cy - y) >= radius + r + margin for x, y, r in placed)


def furnished_room(seed: int = 0) -> World:
    """A 10 m x 8 m room centred on the origin with six pieces of furniture (axis-aligned and
    rotated boxes of 0.5-1.2 m sides), a round pillar and a square pillar.

    The central 4 m x 3 m area (``|x| <= 2``, ``|y| <= 1.5``) is free. ``seed=0`` is a fixed
    layout chosen so that the room's four corners are visible from the origin; any other seed
    places the same pieces at random (deterministically, from ``np.random.default_rng(seed)``),
    inside the room, clear of the central area and of each other.
    """
    hx, hy = _ROOM_HALF
    polys: list[FloatArray] = [box_polygon(0.0, 0.0, 2 * hx, 2 * hy)]
    pieces = [(cx, cy, ln, w, math.radians(th)) for cx, cy, ln, w, th in _FURNITURE]
    pillars = list(_PILLARS)
    if seed != 0:
        rng = np.random.default_rng(seed)
        placed: list[tuple[float, float, float]] = []
        new_pieces = []
        sizes = [(ln, w) for _, _, ln, w, _ in _FURNITURE] + [
            (2 * s, 2 * s) if kind == "round" else (s, s) for kind, _, _, s in _PILLARS
        ]
        for k, (ln, w) in enumerate(sizes):
            radius = 0.5 * math.hypot(ln, w)
            for _attempt in range(10_000):
                cx = float(rng.uniform(-hx, hx))
                cy = float(rng.uniform(-hy, hy))
                if _piece_fits(cx, cy, radius, placed):
                    break
            else:  # pragma: no cover - the room has ample space for these pieces
                raise SimError(f"furnished_room(seed={seed}): could not place piece {k}")
            placed.append((cx, cy, radius))
            # half the boxes axis-aligned, half rotated
            theta = 0.0 if k % 2 == 0 else float(rng.uniform(-math.pi / 2, math.pi / 2))
            new_pieces.append((cx, cy, ln, w, theta))
        n_f = len(_FURNITURE)
        pieces = new_pieces[:n_f]
        pillars = [
            (kind, cx, cy, s)
            for (kind, _, _, s), (cx, cy, _, _, _) in zip(_PILLARS, new_pieces[n_f:])
        ]
    polys += [box_polygon(*p) for p in pieces]
    for kind, cx, cy, s in pillars:
        polys.append(circle_polygon(cx, cy, s) if kind == "round" else box_polygon(cx, cy, s, s))
    return World.from_polygons(polys, name=f"furnished_room(seed={seed})")


def _wall_with_gaps(
    start: tuple[float, float], end: tuple[float, float], gaps: Sequence[tuple[float, float]]
) -> list[FloatArray]:
    """Pieces of the straight wall ``start``-``end`` with the ``gaps`` (as ``(from, to)``
    distances along the wall) cut out, each piece a 2-vertex open polyline."""
    p0, p1 = np.asarray(start, float), np.asarray(end, float)
    length = float(np.hypot(*(p1 - p0)))
    u = (p1 - p0) / length
    cuts = [0.0]
    for g0, g1 in sorted(gaps):
        cuts += [g0, g1]
    cuts.append(length)
    return [
        np.array([p0 + a * u, p0 + b * u]) for a, b in zip(cuts[::2], cuts[1::2]) if b - a > 1e-9
    ]


def office() -> World:
    """A 20 m x 10 m office: a 2 m corridor along the x axis (``|y| <= 1``) with three rooms
    north of it and two south, each entered by a 1 m doorway, and furniture in the rooms.

    Walls are thin segments; the doorway jambs are free wall ends (range jumps, not corners)
    while wall junctions (T and L) are corners.
    """
    X, Y, C = 10.0, 5.0, 1.0
    polys: list[FloatArray] = []
    flags: list[bool] = []

    def add(poly: ArrayLike, closed: bool) -> None:
        polys.append(np.asarray(poly, float))
        flags.append(closed)

    add(box_polygon(0.0, 0.0, 2 * X, 2 * Y), True)  # outer walls
    # corridor walls with doorways: north rooms' doors at x in [-7.5,-6.5], [-0.5,0.5], [6,7]
    for piece in _wall_with_gaps((-X, C), (X, C), [(2.5, 3.5), (9.5, 10.5), (16.0, 17.0)]):
        add(piece, False)
    # south rooms' doors at x in [-4,-3] and [5,6]
    for piece in _wall_with_gaps((-X, -C), (X, -C), [(6.0, 7.0), (15.0, 16.0)]):
        add(piece, False)
    # partitions: north rooms split at x = -3.5 and x = 3.5, south rooms at x = 1
    add([[-3.5, C], [-3.5, Y]], False)
    add([[3.5, C], [3.5, Y]], False)
    add([[1.0, -C], [1.0, -Y]], False)
    # furniture
    for box in (
        (-8.5, 4.2, 1.2, 0.6, 0.0),  # desk, NW room
        (-5.0, 2.5, 0.8, 0.8, math.radians(25.0)),  # box, NW room
        (0.0, 4.3, 1.2, 0.6, 0.0),  # desk, N room
        (2.5, 2.2, 0.6, 0.5, math.radians(-30.0)),  # box, N room
        (8.5, 3.0, 0.6, 1.2, 0.0),  # cabinet, NE room
        (-8.0, -3.8, 1.0, 0.6, math.radians(15.0)),  # desk, SW room
        (-1.5, -2.8, 0.5, 0.5, 0.0),  # box, SW room
        (5.5, -4.2, 1.2, 0.6, 0.0),  # desk, SE room
        (8.3, -2.4, 0.7, 0.7, math.radians(40.0)),  # box, SE room
    ):
        add(box_polygon(*box), True)
    add(box_polygon(-5.0, -3.0, 0.3, 0.3), True)  # square pillar, SW room
    return World.from_polygons(polys, closed=flags, name="office")


def doorway_wall(
    distance: float = 2.0,
    gap: float = 1.0,
    length: float = 10.0,
    back_wall_distance: float | None = None,
) -> World:
    """A straight wall across the x axis at ``x = distance`` (``length`` long, centred on
    ``y = 0``) with a ``gap`` wide doorway centred on ``y = 0``; optionally a second, unbroken
    wall at ``x = back_wall_distance`` behind it."""
    if not (distance > 0 and 0 < gap < length):
        raise SimError(f"need distance > 0 and 0 < gap < length, got {distance}, {gap}, {length}")
    half = length / 2.0
    polys = _wall_with_gaps((distance, -half), (distance, half), [(half - gap / 2, half + gap / 2)])
    if back_wall_distance is not None:
        if not back_wall_distance > distance:
            raise SimError(
                f"back_wall_distance must exceed distance ({distance}), got {back_wall_distance}"
            )
        polys.append(np.array([[back_wall_distance, -half], [back_wall_distance, half]]))
    return World.from_polygons(polys, closed=False, name="doorway_wall")


#: gym: hall half-sizes (a 30 m x 20 m hall centred on the origin)
GYM_HALF = (15.0, 10.0)
#: gym doorways (1.5 m wide): (wall, from, to) along the wall's free coordinate
_GYM_DOORS = (
    ("north", -5.0, -3.5),  # into a closed 1.5 m x 2.5 m vestibule
    ("south", 5.0, 6.5),  # into a 3 m corridor stub, open at its far end
    ("west", -3.5, -2.0),  # nothing behind: an open door
)
#: gym pillars, a ring round the free middle: ("square", cx, cy, side, theta_deg) or
#: ("round", cx, cy, radius, 0)
_GYM_PILLARS = (
    ("square", 7.0, 1.0, 0.6, 0.0),
    ("square", 4.5, 5.5, 0.6, 0.0),
    ("round", 0.0, 7.0, 0.4, 0.0),
    ("square", -5.0, 5.0, 0.8, 30.0),
    ("round", -7.0, 0.0, 0.3, 0.0),
    ("square", -4.5, -5.5, 0.6, 0.0),
    ("square", 0.5, -7.0, 0.6, 45.0),
    ("round", 5.0, -5.0, 0.3, 0.0),
)
#: gym benches and equipment: (cx, cy, length, width, theta_deg)
_GYM_FURNITURE = (
    (2.5, 9.6, 5.0, 0.4, 0.0),  # bench along the north wall
    (-3.0, -9.6, 5.0, 0.4, 0.0),  # bench along the south wall
    (14.6, 4.0, 4.0, 0.4, 90.0),  # bench along the east wall
    (-14.6, 4.5, 3.0, 0.4, 90.0),  # bench along the west wall
    (8.8, -2.5, 1.6, 0.8, 20.0),  # vaulting box
    (-2.5, 8.6, 2.0, 1.0, -10.0),  # stack of mats
    (-8.6, 3.0, 1.2, 0.6, -30.0),  # table
    (3.0, -8.6, 1.0, 1.0, 15.0),  # crate of balls
    (-8.0, -5.5, 1.4, 0.7, 60.0),  # springboard
    (8.0, 5.0, 1.0, 0.5, 0.0),  # box
)
#: the free middle of the gym: nothing within this distance of the origin
GYM_FREE_RADIUS = 6.5


def gym() -> World:
    """A 30 m x 20 m sports hall centred on the origin, like the paper's gym (§5).

    - Outer walls at ``|x| = 15``, ``|y| = 10`` with three 1.5 m doorways: north at
      ``x ∈ [-5, -3.5]`` into a closed 1.5 m x 2.5 m vestibule, south at ``x ∈ [5, 6.5]`` into a
      3 m corridor stub open at its far end, west at ``y ∈ [-3.5, -2]`` with nothing behind
      (beams through the open ones read "no return").
    - A ring of eight pillars 7 m or so from the centre: five square (0.6 m, one 0.8 m; one
      turned 30°, one 45°) and three round (16-gons of radius 0.3-0.4 m, no corners).
    - Benches (0.4 m deep, 0.2 m off the wall) along all four walls, and six boxes of gym
      equipment (vaulting box, mats, table, crate, springboard, box; most turned) 8-9 m out.

    Nothing lies within ``GYM_FREE_RADIUS`` = 6.5 m of the origin, so a robot can drive circles
    of radius 3-5 m round it (1.5 m clear of everything at 5 m). The walls are mostly beyond an
    8 m scanner's reach from there; the pillars and equipment are not: on a 3 m or 4 m circle
    a forward 180° scanner with an 8 m range sees at least two true corners
    (:func:`visible_corners`) almost everywhere. Deterministic.
    """
    X, Y = GYM_HALF
    polys: list[FloatArray] = []
    flags: list[bool] = []

    def add(poly: ArrayLike, closed: bool) -> None:
        polys.append(np.asarray(poly, float))
        flags.append(closed)

    # outer walls, each cut at its doorways (gaps as distances along the wall from its start)
    walls = {
        "south": ((-X, -Y), (X, -Y)),
        "east": ((X, -Y), (X, Y)),
        "north": ((X, Y), (-X, Y)),
        "west": ((-X, Y), (-X, -Y)),
    }
    for wall, (start, end) in walls.items():
        gaps = []
        for w, a, b in _GYM_DOORS:
            if w != wall:
                continue
            # distance along the wall of the coordinate a, b: walls run anticlockwise
            if wall == "south":
                gaps.append((a + X, b + X))
            elif wall == "north":
                gaps.append((X - b, X - a))
            elif wall == "west":
                gaps.append((Y - b, Y - a))
            else:  # pragma: no cover - no door in the east wall
                gaps.append((a + Y, b + Y))
        for piece in _wall_with_gaps(start, end, gaps):
            add(piece, False)
    # north vestibule (closed) and south corridor stub (open at its end)
    add([[-5.0, Y], [-5.0, Y + 2.5], [-3.5, Y + 2.5], [-3.5, Y]], False)
    add([[5.0, -Y], [5.0, -Y - 3.0]], False)
    add([[6.5, -Y], [6.5, -Y - 3.0]], False)
    for kind, cx, cy, size, theta_deg in _GYM_PILLARS:
        if kind == "round":
            add(circle_polygon(cx, cy, size), True)
        else:
            add(box_polygon(cx, cy, size, size, math.radians(theta_deg)), True)
    for cx, cy, length, width, theta_deg in _GYM_FURNITURE:
        add(box_polygon(cx, cy, length, width, math.radians(theta_deg)), True)
    return World.from_polygons(polys, closed=flags, name="gym")


#: the built-in worlds :func:`world_by_name` knows, each built with its defaults
_WORLD_FACTORIES: dict[str, Callable[[], World]] = {
    "gym": gym,
    "office": office,
    "furnished_room": furnished_room,
    "rectangular_room": rectangular_room,
}
#: the names :func:`world_by_name` accepts
WORLD_NAMES: tuple[str, ...] = tuple(_WORLD_FACTORIES)


def world_by_name(name: str) -> World:
    """The built-in world called ``name``: one of ``"gym"``, ``"office"``,
    ``"furnished_room"`` (seed 0) or ``"rectangular_room"`` (8 m x 6 m). An unknown name raises
    :class:`SimError` listing the known ones."""
    try:
        factory = _WORLD_FACTORIES[str(name)]
    except KeyError:
        raise SimError(f"unknown world {name!r}; known worlds: {', '.join(WORLD_NAMES)}") from None
    return factory()
