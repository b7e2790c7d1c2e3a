"""Tests of the gym, world lookup by name, rays staying inside the built-in worlds, and world
files (TOML/JSON round trips and every kind of bad file)."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from fuzzypos import sim
from fuzzypos.geometry import Pose2D
from fuzzypos.sim import (
    GYM_FREE_RADIUS,
    ScannerModel,
    SimError,
    World,
    cast_rays,
    gym,
    office,
    visible_corners,
    world_by_name,
)

#: gym doorways: the open west door, and the south corridor stub's open end
WEST_DOOR = (-3.5, -2.0)  # y range at x = -15
SOUTH_STUB = (5.0, 6.5)  # x range of the stub, open at y = -13


def _rowwise_distance(points: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Distance from ``points[i]`` to the segment ``seg[i]`` (one segment per point)."""
    a, e = seg[:, :2], seg[:, 2:] - seg[:, :2]
    w = points - a
    u = np.clip(np.sum(w * e, axis=1) / np.sum(e * e, axis=1), 0.0, 1.0)
    return np.hypot(*(w - u[:, None] * e).T)


def _as_set(points: np.ndarray) -> set[tuple[float, float]]:
    return {(round(float(x), 6), round(float(y), 6)) for x, y in points}


# ---------------------------------------------------------------------------------------------
# the gym
# ---------------------------------------------------------------------------------------------


def test_gym_layout() -> None:
    world = gym()
    assert world.name == "gym"
    assert world.bounds == (-15.0, -13.0, 15.0, 12.5)  # the hall plus the vestibule and stub
    # the hall's four corners are corners
    assert {(15.0, 10.0), (-15.0, 10.0), (15.0, -10.0), (-15.0, -10.0)} <= _as_set(world.corners)
    # square and round pillars: 4-gons of side 0.6-0.8 m and 16-gons
    closed = [p for p, c in zip(world.polygons, world.closed) if c]
    round_ = [p for p in closed if len(p) == 16]
    square = [p for p in closed if len(p) == 4 and np.ptp(np.hypot(*np.diff(p, axis=0).T)) < 1e-9]
    assert len(round_) >= 2 and len(square) >= 4
    # the free middle: room for circles of radius 3-5 m, 1.5 m clear of everything at 5 m
    a = np.linspace(0.0, 2.0 * math.pi, 720, endpoint=False)
    ring = np.column_stack([np.cos(a), np.sin(a)])
    assert world.distance(np.zeros((1, 2)))[0] >= GYM_FREE_RADIUS
    assert world.distance(5.0 * ring).min() >= 1.5
    # deterministic
    np.testing.assert_array_equal(gym().segments, world.segments)


def test_gym_doorways() -> None:
    world = gym()
    r = cast_rays(
        world,
        [(-12.0, -2.75), (-4.25, 5.0), (5.75, -5.0), (-12.0, 7.0)],
        [math.pi, math.pi / 2, -math.pi / 2, math.pi],
    )
    assert np.isinf(r[0])  # out through the open west door
    assert r[1] == pytest.approx(7.5, abs=1e-9)  # into the vestibule, to its back wall
    assert np.isinf(r[2])  # down the south corridor stub, out of its open end
    assert r[3] == pytest.approx(3.0, abs=1e-9)  # the west wall, above the bench


def test_gym_circle_sees_corners() -> None:
    """From a 4 m circle round the centre, a SICK LMS200 sees at least two true corners almost
    everywhere (pillars and equipment, not the far walls)."""
    world = gym()
    scanner = ScannerModel.sick_lms200()
    path = sim.CommandedPath.circle(4.0, 1)
    poses = path.poses(np.linspace(0.0, path.duration, 60, endpoint=False))
    n = np.array([len(visible_corners(world, p, scanner)) for p in poses])
    assert n.min() >= 1 and (n >= 2).mean() >= 0.9


def _inside_gym(points: np.ndarray) -> np.ndarray:
    x, y = points[:, 0], points[:, 1]
    hall = (np.abs(x) <= 15.0 + 1e-9) & (np.abs(y) <= 10.0 + 1e-9)
    vestibule = (x >= -5.0 - 1e-9) & (x <= -3.5 + 1e-9) & (y >= 10.0 - 1e-9) & (y <= 12.5 + 1e-9)
    stub = (x >= 5.0 - 1e-9) & (x <= 6.5 + 1e-9) & (y <= -10.0 + 1e-9) & (y >= -13.0 - 1e-9)
    return hall | vestibule | stub


def test_no_ray_leaves_the_gym_except_through_a_doorway() -> None:
    world = gym()
    rng = np.random.default_rng(17)
    # origins in the free middle and near the walls, clear of every obstacle
    cand = np.column_stack([rng.uniform(-14.5, 14.5, 400), rng.uniform(-9.5, 9.5, 400)])
    origins = cand[world.distance(cand) > 0.05][:60]
    origins = origins[np.hypot(origins[:, 0], origins[:, 1]) < 14.0]
    inside_obstacle = np.zeros(len(origins), dtype=bool)
    for p, c in zip(world.polygons, world.closed):
        if c:  # even-odd ray test against the closed polygon's edges
            e = np.roll(p, -1, axis=0)
            with np.errstate(divide="ignore", invalid="ignore"):
                cross = ((p[:, 1] > origins[:, None, 1]) != (e[:, 1] > origins[:, None, 1])) & (
                    origins[:, None, 0]
                    < p[:, 0]
                    + (origins[:, None, 1] - p[:, 1]) * (e[:, 0] - p[:, 0]) / (e[:, 1] - p[:, 1])
                )
            inside_obstacle |= cross.sum(axis=1) % 2 == 1
    origins = origins[~inside_obstacle]
    assert len(origins) >= 30
    dirs = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    o = np.repeat(origins, len(dirs), axis=0)
    a = np.tile(dirs, len(origins))
    r, idx = cast_rays(world, o, a, 100.0, return_segment=True)
    hit = np.isfinite(r)
    d = np.column_stack([np.cos(a), np.sin(a)])
    pts = o[hit] + r[hit, None] * d[hit]
    # every hit lies on the segment it names, inside the hall (or its vestibule and stub)
    assert np.max(_rowwise_distance(pts, world.segments[idx[hit]])) <= 1e-9
    assert _inside_gym(pts).all()
    # every miss leaves through the west door or the south stub's open end
    miss_o, miss_d = o[~hit], d[~hit]
    assert len(miss_o) > 0
    west = miss_d[:, 0] < 0
    t_w = (-15.0 - miss_o[:, 0]) / np.where(west, miss_d[:, 0], -1.0)
    y_w = miss_o[:, 1] + t_w * miss_d[:, 1]
    through_west = west & (y_w >= WEST_DOOR[0] - 1e-9) & (y_w <= WEST_DOOR[1] + 1e-9)
    south = miss_d[:, 1] < 0
    t_s = (-13.0 - miss_o[:, 1]) / np.where(south, miss_d[:, 1], -1.0)
    x_s = miss_o[:, 0] + t_s * miss_d[:, 0]
    through_stub = south & (x_s >= SOUTH_STUB[0] - 1e-9) & (x_s <= SOUTH_STUB[1] + 1e-9)
    assert np.all(through_west | through_stub)


def test_no_ray_leaves_the_office() -> None:
    world = office()
    rng = np.random.default_rng(4)
    origins = np.column_stack([rng.uniform(-9.5, 9.5, 50), rng.uniform(-0.8, 0.8, 50)])
    dirs = rng.uniform(-math.pi, math.pi, (50, 400))
    o = np.repeat(origins, 400, axis=0)
    r, idx = cast_rays(world, o, dirs.ravel(), 100.0, return_segment=True)
    assert np.isfinite(r).all() and (idx >= 0).all()
    pts = o + r[:, None] * np.column_stack([np.cos(dirs.ravel()), np.sin(dirs.ravel())])
    assert np.all(np.abs(pts[:, 0]) <= 10.0 + 1e-9) and np.all(np.abs(pts[:, 1]) <= 5.0 + 1e-9)
    assert np.max(_rowwise_distance(pts, world.segments[idx])) <= 1e-9


def test_scans_in_the_gym_land_on_walls() -> None:
    world = gym()
    scanner = ScannerModel.sick_lms200(
        range_noise_std=0.0,
        range_noise_per_metre=0.0,
        incidence_noise=0.0,
        dropout_probability=0.0,
        spurious_probability=0.0,
    )
    for th in np.linspace(-math.pi, math.pi, 8, endpoint=False):
        pose = Pose2D(4.0 * math.cos(th), 4.0 * math.sin(th), th + math.pi / 2)
        scan = sim.simulate_scan(world, pose, scanner)
        pts = pose.transform_points(scan.points_robot()[scan.valid])
        assert len(pts) > 10 and np.max(world.distance(pts)) <= 1e-9


# ---------------------------------------------------------------------------------------------
# worlds by name
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["gym", "office", "furnished_room", "rectangular_room"])
def test_world_by_name(name: str) -> None:
    world = world_by_name(name)
    assert isinstance(world, World) and world.name.startswith(name)
    assert name in sim.WORLD_NAMES


def test_world_by_name_unknown_lists_the_known_ones() -> None:
    with pytest.raises(SimError, match="unknown world 'hall'") as info:
        world_by_name("hall")
    for name in ("gym", "office", "furnished_room", "rectangular_room"):
        assert name in str(info.value)


# ---------------------------------------------------------------------------------------------
# world files
# ---------------------------------------------------------------------------------------------


def _same_world(a: World, b: World) -> None:
    assert a.name == b.name
    np.testing.assert_array_equal(a.segments, b.segments)
    assert a.closed == b.closed and len(a.polygons) == len(b.polygons)
    for p, q in zip(a.polygons, b.polygons):
        np.testing.assert_array_equal(p, q)


@pytest.mark.parametrize(
    "make", [gym, office, lambda: sim.furnished_room(3), sim.rectangular_room, sim.doorway_wall]
)
def test_world_file_round_trip(make, tmp_path: Path) -> None:
    world = make()
    path = tmp_path / "world.toml"
    world.to_file(path)
    back = World.from_file(path)
    _same_world(world, back)
    assert _as_set(back.corners) == _as_set(world.corners)
    # the file is TOML: a second round trip writes the same text
    back.to_file(tmp_path / "again.toml")
    assert (tmp_path / "again.toml").read_text() == path.read_text()


def test_world_file_with_loose_segments_and_odd_numbers(tmp_path: Path) -> None:
    room = sim.rectangular_room()
    segs = np.vstack([room.segments, [[0.1, 1e-17, 1.0 / 3.0, 2.0 / 3.0]], [[-1e6, 0.0, 1e6, 1.0]]])
    world = World(segs, name='odd "name"\twith tab', polygons=room.polygons, closed=room.closed)
    world.to_file(tmp_path / "w")
    _same_world(world, World.from_file(tmp_path / "w"))
    # segments only
    bare = World.from_segments(segs[:3], name="bare")
    bare.to_file(tmp_path / "bare.toml")
    back = World.from_file(tmp_path / "bare.toml")
    np.testing.assert_array_equal(back.segments, bare.segments)
    assert back.polygons == ()
    # a hand-built world whose segments are not its polygons' edges: written as segments
    odd = World(segs[4:], polygons=room.polygons, closed=room.closed)
    odd.to_file(tmp_path / "odd.toml")
    np.testing.assert_array_equal(World.from_file(tmp_path / "odd.toml").segments, odd.segments)


TOML_TEXT = """
name = "two walls and a box"
[[polygon]]
points = [[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]]   # closing point repeated: dropped
[[polygon]]
points = [[3, 0], [5, 0], [5, 2]]
closed = false
[[segment]]
start = [-1, -1]
end = [-1.0, 4.5]
"""


def test_world_file_formats_are_told_apart_by_content(tmp_path: Path) -> None:
    doc = {
        "name": "two walls and a box",
        "polygon": [
            {"points": [[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]]},
            {"points": [[3, 0], [5, 0], [5, 2]], "closed": False},
        ],
        "segment": [{"start": [-1, -1], "end": [-1.0, 4.5]}],
    }
    # JSON in a .toml file (after blank lines), TOML in a .json file: content decides
    (tmp_path / "a.toml").write_text("\n  \n " + json.dumps(doc, indent=1))
    (tmp_path / "b.json").write_text(TOML_TEXT)
    a = World.from_file(tmp_path / "a.toml")
    b = World.from_file(str(tmp_path / "b.json"))
    _same_world(a, b)
    assert a.name == "two walls and a box" and a.closed == (True, False)
    assert a.n_segments == 4 + 2 + 1
    np.testing.assert_array_equal(a.segments[-1], [-1.0, -1.0, -1.0, 4.5])
    # the name defaults to the file's stem
    (tmp_path / "unnamed.cfg").write_text("[[segment]]\nstart = [0, 0]\nend = [1, 0]\n")
    assert World.from_file(tmp_path / "unnamed.cfg").name == "unnamed"


BAD_FILES = [
    ("name = 'x'\n[[polygon\npoints = []", "invalid TOML"),
    ('{"name": "x", "polygon": [}', "invalid JSON"),
    ("[1, 2]", "invalid TOML"),  # not a table: TOML rejects it
    ('{"name": "x"', "invalid JSON"),
    (
        "  [[polygon]]\npoints = [[0, 0], [1, 0], [1, 1]]\n[[wall]]\nstart = [0, 0]",
        "unknown key 'wall'",
    ),
    ("name = 3\n[[segment]]\nstart = [0, 0]\nend = [1, 0]", "'name' must be a string"),
    ("[[polygon]]\nclosed = true", "polygon 1: missing 'points'"),
    (
        "[[polygon]]\npoints = [[0,0],[1,0],[1,1]]\n[[polygon]]\nclosed = true",
        "polygon 2: missing 'points'",
    ),
    (
        "[[polygon]]\npoints = [[0,0],[1,0],[1,1]]\ncolour = 'red'",
        "polygon 1: unknown key 'colour'",
    ),
    ("[[polygon]]\npoints = 5", "polygon 1: 'points' must be a list"),
    ("[[polygon]]\npoints = [[0, 0], [1, 0, 2], [1, 1]]", "polygon 1, point 2: expected a point"),
    ("[[polygon]]\npoints = [[0, 0], 7, [1, 1]]", "polygon 1, point 2: expected a point"),
    (
        "[[polygon]]\npoints = [[0, 0], [1, 'a'], [1, 1]]",
        "polygon 1, point 2: coordinate 'a' is not a number",
    ),
    ("[[polygon]]\npoints = [[0, 0], [1, true], [1, 1]]", "coordinate True is not a number"),
    (
        "[[polygon]]\npoints = [[0, 0], [1, nan], [1, 1]]",
        "polygon 1, point 2: coordinate nan is not finite",
    ),
    ('{"polygon": [{"points": [[0, 0], [Infinity, 0], [1, 1]]}]}', "coordinate inf is not finite"),
    (
        "[[polygon]]\npoints = [[0, 0], [1, 0]]",
        "polygon 1: a closed polygon needs at least 3 points, got 2",
    ),
    ("[[polygon]]\npoints = [[0, 0]]\nclosed = false", "needs at least 2 points, got 1"),
    (
        "[[polygon]]\npoints = [[0, 0], [1, 0], [1, 0], [0, 1]]",
        "polygon 1: points 2 and 3 coincide",
    ),
    ("[[polygon]]\npoints = [[0, 0], [1, 0], [1, 0], [0, 1]]\nclosed = false", "zero-length edge"),
    ("[[polygon]]\npoints = [[0, 0], [1, 0], [1, 1], [0, 0], [0, 0]]", "points 4 and 1 coincide"),
    (
        "[[polygon]]\npoints = [[0, 0], [1, 0], [1, 1]]\nclosed = 'yes'",
        "'closed' must be true or false",
    ),
    ("polygon = 3", "'polygon' must be a list of tables"),
    ('{"polygon": [[0, 0], [1, 0]]}', "'polygon' must be a list of tables"),
    ("[[segment]]\nstart = [0, 0]", "segment 1: missing 'end'"),
    (
        "[[segment]]\nstart = [0, 0]\nend = [1, 'x']",
        "segment 1, end: coordinate 'x' is not a number",
    ),
    ("[[segment]]\nstart = [2, 3]\nend = [2, 3]", "segment 1: start and end coincide"),
    ("[[segment]]\nstart = [0, 0]\nend = [1, 0]\nwidth = 2", "segment 1: unknown key 'width'"),
    ("name = 'empty'", "no walls"),
    ("", "no walls"),
    ('{"name": "x", "polygon": []}', "no walls"),
    ("[]", "invalid TOML"),
    ('{"a": 1} ', "unknown key 'a'"),
    ("   {}", "no walls"),
]


@pytest.mark.parametrize("text, match", BAD_FILES)
def test_bad_world_files(text: str, match: str, tmp_path: Path) -> None:
    path = tmp_path / "bad_world.toml"
    path.write_text(text)
    with pytest.raises(SimError) as info:
        World.from_file(path)
    msg = str(info.value)
    assert msg.startswith(f"world file {path}:"), msg
    assert match in msg, msg


def test_json_top_level_must_be_an_object(tmp_path: Path) -> None:
    path = tmp_path / "list.json"
    path.write_text('{"polygon": 1}')
    with pytest.raises(SimError, match="list of tables"):
        World.from_file(path)
    # a JSON text that is not an object cannot start with "{", so it is read as TOML
    path.write_text("[[1, 2]]")
    with pytest.raises(SimError, match="invalid TOML"):
        World.from_file(path)


def test_unreadable_world_files(tmp_path: Path) -> None:
    missing = tmp_path / "nope.toml"
    with pytest.raises(SimError, match=f"world file {missing}: cannot read it"):
        World.from_file(missing)
    with pytest.raises(SimError, match="cannot read it"):
        World.from_file(tmp_path)  # a directory
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"name = '\xff\xfe'\n")
    with pytest.raises(SimError, match=f"world file {binary}: cannot read it"):
        World.from_file(binary)


def test_unwritable_world_files(tmp_path: Path) -> None:
    with pytest.raises(SimError, match=f"world file {tmp_path}: cannot write it"):
        sim.rectangular_room().to_file(tmp_path)
    empty = World.from_segments(np.empty((0, 4)), name="void")
    with pytest.raises(SimError, match="has no walls"):
        empty.to_file(tmp_path / "void.toml")


_coord = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12)


@given(st.lists(st.tuples(_coord, _coord), min_size=2, max_size=12, unique=True), st.booleans())
def test_world_file_round_trip_is_bit_exact(
    points: list[tuple[float, float]], closed: bool
) -> None:
    pts = np.array(points, dtype=float)
    step = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assume(np.all(step > 1e-9) and np.all(np.isfinite(step)))
    assume(not closed or len(pts) >= 3)
    world = World.from_polygons([pts], closed=closed, name="random")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "w.toml"
        world.to_file(path)
        _same_world(world, World.from_file(path))
