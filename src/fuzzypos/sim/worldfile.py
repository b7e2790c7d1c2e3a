"""World files: a small TOML or JSON description of a :class:`~fuzzypos.sim.World`.

The format is told apart by content, not by the file's suffix: a text whose first non-blank
character is ``{`` is JSON, anything else TOML. Both hold the same keys::

    name = "two rooms"              # optional; default: the file's stem

    [[polygon]]                     # any number of polygons
    points = [[0, 0], [8, 0], [8, 6], [0, 6]]
    closed = true                   # optional, default true (false: an open polyline)

    [[segment]]                     # any number of single walls
    start = [4.0, 0.0]
    end = [4.0, 2.5]

or in JSON ``{"name": ..., "polygon": [{"points": [...], "closed": true}], "segment":
[{"start": [x, y], "end": [x, y]}]}``. Coordinates are metres (integers or floats). The world's
walls are the polygons' edges followed by the segments, in file order. Polygons and segments
are numbered from 1 in error messages, in file order; points likewise within a polygon.

A bad file raises :class:`~fuzzypos.sim.SimError` whose message starts with
``world file <path>:`` and says what is wrong: unreadable, invalid TOML/JSON, unknown or missing
keys, a non-numeric or non-finite coordinate, a point that is not an ``[x, y]`` pair, too few
points, a zero-length edge or segment, or no walls at all.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np

from ..errors import FuzzyposError
from .base import FloatArray, SimError, _polygon_segments

if sys.version_info >= (3, 11):  # pragma: no cover - depends on the interpreter
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["WorldParts", "read_world_file", "save_world", "world_to_toml"]

_TOP_KEYS = ("name", "polygon", "segment")
_POLYGON_KEYS = ("points", "closed")
_SEGMENT_KEYS = ("start", "end")


class WorldParts(NamedTuple):
    """What a world file holds, as :class:`~fuzzypos.sim.World` takes it: every wall segment
    (the polygons' edges first), the name, the polygons and whether each is closed."""

    segments: FloatArray
    name: str
    polygons: tuple[FloatArray, ...]
    closed: tuple[bool, ...]


class WorldLike(Protocol):
    """What :func:`world_to_toml` reads of a world (a :class:`~fuzzypos.sim.World`)."""

    @property
    def name(self) -> str: ...
    @property
    def segments(self) -> FloatArray: ...
    @property
    def polygons(self) -> tuple[FloatArray, ...]: ...
    @property
    def closed(self) -> tuple[bool, ...]: ...
    @property
    def n_segments(self) -> int: ...


class _Bad(FuzzyposError):
    """A problem in the file's content (the message lacks the file prefix)."""


def _check_keys(table: dict[str, Any], allowed: tuple[str, ...], where: str) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise _Bad(
            f"{where}: unknown key {unknown[0]!r} (expected {', '.join(map(repr, allowed))})"
        )


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _Bad(f"{where}: coordinate {value!r} is not a number")
    v = float(value)
    if not math.isfinite(v):
        raise _Bad(f"{where}: coordinate {value!r} is not finite")
    return v


def _point(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise _Bad(f"{where}: expected a point [x, y], got {value!r}")
    return _number(value[0], where), _number(value[1], where)


def _table_list(data: dict[str, Any], key: str) -> list[dict[str, Any]]:
    entries = data.get(key, [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise _Bad(
            f"{key!r} must be a list of tables ([[{key}]] in TOML, a list of objects in JSON)"
        )
    return entries


def _polygon(entry: dict[str, Any], i: int) -> tuple[FloatArray, bool]:
    where = f"polygon {i}"
    _check_keys(entry, _POLYGON_KEYS, where)
    if "points" not in entry:
        raise _Bad(f"{where}: missing 'points'")
    closed = entry.get("closed", True)
    if not isinstance(closed, bool):
        raise _Bad(f"{where}: 'closed' must be true or false, got {closed!r}")
    raw = entry["points"]
    if not isinstance(raw, list):
        raise _Bad(f"{where}: 'points' must be a list of [x, y] points, got {raw!r}")
    pts = [_point(p, f"{where}, point {j}") for j, p in enumerate(raw, start=1)]
    v = np.array(pts, dtype=float).reshape(-1, 2)
    if closed and len(v) >= 2 and np.array_equal(v[0], v[-1]):
        v = v[:-1]  # a closed polygon written with its first point repeated at the end
    need = 3 if closed else 2
    if len(v) < need:
        kind = "closed polygon" if closed else "open polyline (closed = false)"
        raise _Bad(f"{where}: a {kind} needs at least {need} points, got {len(v)}")
    nxt = np.roll(v, -1, axis=0) if closed else v[1:]
    step = nxt - (v if closed else v[:-1])
    zero = np.flatnonzero(np.hypot(step[:, 0], step[:, 1]) <= 1e-12)
    if len(zero):
        j = int(zero[0])
        k = (j + 1) % len(v)
        raise _Bad(
            f"{where}: points {j + 1} and {k + 1} coincide at {v[j].tolist()} (a zero-length edge)"
        )
    return v, closed


def _segment(entry: dict[str, Any], i: int) -> FloatArray:
    where = f"segment {i}"
    _check_keys(entry, _SEGMENT_KEYS, where)
    for key in _SEGMENT_KEYS:
        if key not in entry:
            raise _Bad(f"{where}: missing {key!r}")
    a = _point(entry["start"], f"{where}, start")
    b = _point(entry["end"], f"{where}, end")
    if math.hypot(b[0] - a[0], b[1] - a[1]) <= 1e-12:
        raise _Bad(f"{where}: start and end coincide at {list(a)} (a zero-length segment)")
    return np.array([*a, *b], dtype=float)


def _world_from_data(data: Any, default_name: str) -> WorldParts:
    if not isinstance(data, dict):
        raise _Bad(f"the top level must be a table (a JSON object), got {type(data).__name__}")
    _check_keys(data, _TOP_KEYS, "top level")
    name = data.get("name", default_name)
    if not isinstance(name, str):
        raise _Bad(f"'name' must be a string, got {name!r}")
    polys = [_polygon(e, i) for i, e in enumerate(_table_list(data, "polygon"), start=1)]
    segs = [_segment(e, i) for i, e in enumerate(_table_list(data, "segment"), start=1)]
    if not polys and not segs:
        raise _Bad("no walls: give at least one [[polygon]] or [[segment]]")
    parts = [_polygon_segments(v, c) for v, c in polys]
    if segs:
        parts.append(np.vstack(segs))
    return WorldParts(
        np.vstack(parts),
        name=name,
        polygons=tuple(v for v, _ in polys),
        closed=tuple(c for _, c in polys),
    )


def read_world_file(path: str | os.PathLike[str]) -> WorldParts:
    """Read the world file ``path`` (TOML or JSON, told apart by content) into the parts
    :meth:`~fuzzypos.sim.World.from_file` builds its world of."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SimError(f"world file {p}: cannot read it: {exc}") from exc
    if text.lstrip().startswith("{"):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SimError(f"world file {p}: invalid JSON: {exc}") from exc
    else:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SimError(f"world file {p}: invalid TOML: {exc}") from exc
    try:
        return _world_from_data(data, p.stem)
    except _Bad as exc:
        raise SimError(f"world file {p}: {exc}") from None


def _loose_segments(world: WorldLike) -> tuple[bool, FloatArray]:
    """Whether the world's segments start with its polygons' edges, and the rest."""
    if not world.polygons:
        return True, world.segments
    edges = np.vstack([_polygon_segments(v, c) for v, c in zip(world.polygons, world.closed)])
    n = len(edges)
    if len(world.segments) >= n and np.array_equal(world.segments[:n], edges):
        return True, world.segments[n:]
    return False, world.segments


def _toml_point(x: float, y: float) -> str:
    return f"[{float(x)!r}, {float(y)!r}]"  # repr: the shortest text that reads back exactly


def _toml_points(points: FloatArray, per_line: int = 4) -> str:
    items = [_toml_point(x, y) for x, y in points]
    if len(items) <= per_line:
        return "[" + ", ".join(items) + "]"
    lines = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    return "[\n" + "".join(f"    {line},\n" for line in lines) + "]"


def world_to_toml(world: WorldLike) -> str:
    """The TOML text :func:`save_world` writes: its name, its polygons (with ``closed``) and
    the segments that are not polygon edges, one compact ``[x, y]`` pair per point. A world
    whose segments do not start with its polygons' edges (built by hand) is written as
    segments only."""
    import tomli_w

    if world.n_segments == 0:
        raise SimError(f"the world {world.name!r} has no walls to write")
    consistent, loose = _loose_segments(world)
    chunks = [tomli_w.dumps({"name": world.name})]  # tomli_w quotes and escapes the name
    if consistent:
        for v, c in zip(world.polygons, world.closed):
            chunks.append(
                f"\n[[polygon]]\npoints = {_toml_points(v)}\nclosed = {'true' if c else 'false'}\n"
            )
    for x1, y1, x2, y2 in loose:
        chunks.append(
            f"\n[[segment]]\nstart = {_toml_point(x1, y1)}\nend = {_toml_point(x2, y2)}\n"
        )
    return "".join(chunks)


def save_world(world: WorldLike, path: str | os.PathLike[str]) -> None:
    """Write ``world`` as TOML (:func:`world_to_toml`) to ``path``;
    :meth:`~fuzzypos.sim.World.from_file` reads it back with bit-identical coordinates."""
    p = Path(path)
    try:
        text = world_to_toml(world)
    except SimError as exc:
        raise SimError(f"world file {p}: {exc}") from None
    try:
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise SimError(f"world file {p}: cannot write it: {exc}") from exc
