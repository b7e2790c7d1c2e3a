"""Localisation in a known map (issue 37) on simulated worlds: two identical rooms and a
corridor that looks the same both ways keep it searching (never a confident wrong pose);
a difference seen resolves it; an initial pose is tracked at once; a kidnapped robot is
noticed and relocalised; bad initial poses raise; the map's field is cached beside the map
and a read-only folder is no error."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

import fuzzypos.localization.field
from fuzzypos.config import Config
from fuzzypos.errors import FuzzyposError
from fuzzypos.geometry import Pose2D, compose, inverse, relative
from fuzzypos.io.occupancy_map import FREE, OCCUPIED, UNKNOWN, OccupancyMap, read_map_yaml
from fuzzypos.localization import (
    InitialPoseError,
    LocalizationEstimate,
    Localizer,
    LocalizerState,
)
from fuzzypos.localization.field import CACHE_SUFFIX
from fuzzypos.sim import (
    ScannerModel,
    World,
    box_polygon,
    office,
    rectangular_room,
    simulate_scan,
)

RES = 0.05
SCANNER = ScannerModel(n_beams=180, range_max=10.0, range_noise_std=0.01)
ROUND = ScannerModel(
    n_beams=361, field_of_view_deg=360.0, angle_min_deg=-180.0, range_max=10.0, range_noise_std=0.01
)


def map_of(world: World, seeds: list[tuple[float, float]], margin: float = 1.0) -> OccupancyMap:
    """The world's walls drawn into cells (occupied), the space reachable from ``seeds``
    without crossing a wall free, the rest unknown."""
    seg = world.segments
    lo = np.minimum(seg[:, :2], seg[:, 2:]).min(axis=0) - margin
    hi = np.maximum(seg[:, :2], seg[:, 2:]).max(axis=0) + margin
    shape = (math.ceil((hi[1] - lo[1]) / RES), math.ceil((hi[0] - lo[0]) / RES))
    wall = np.zeros(shape, dtype=bool)
    for x1, y1, x2, y2 in seg:
        n = max(2, int(math.hypot(x2 - x1, y2 - y1) / (RES / 4)))
        t = np.linspace(0.0, 1.0, n)
        cols = ((x1 + t * (x2 - x1) - lo[0]) / RES).astype(int)
        rows = ((y1 + t * (y2 - y1) - lo[1]) / RES).astype(int)
        wall[rows, cols] = True
    labels, _ = ndimage.label(~wall)
    cells = np.full(shape, UNKNOWN, dtype=np.int8)
    for x, y in seeds:
        cells[labels == labels[int((y - lo[1]) / RES), int((x - lo[0]) / RES)]] = FREE
    cells[wall] = OCCUPIED
    return OccupancyMap(cells, RES, (float(lo[0]), float(lo[1]), 0.0))


Poses = list[tuple[float, float, float]]


def run(
    loc: Localizer,
    world: World,
    poses: Poses,
    scanner: ScannerModel = SCANNER,
    odometry: Poses | None = None,
    seed: int = 0,
) -> list[LocalizationEstimate]:
    """The localizer's estimates along ``poses`` (odometry: the true poses unless given)."""
    rng = np.random.default_rng(seed)
    odometry = poses if odometry is None else odometry
    out = []
    for k, (pose, odom) in enumerate(zip(poses, odometry)):
        scan = simulate_scan(world, Pose2D(*pose), scanner, rng, stamp=0.1 * k, index=k)
        out.append(loc.update(scan, odom))
    return out


def error(est: LocalizationEstimate, truth: tuple[float, float, float]) -> tuple[float, float]:
    assert est.pose is not None
    turn = (est.pose.theta - truth[2] + math.pi) % (2 * math.pi) - math.pi
    return math.hypot(est.pose.x - truth[0], est.pose.y - truth[1]), abs(turn)


def no_wrong_pose(estimates: list[LocalizationEstimate], poses: list) -> None:
    """Every localised estimate lies within 0.3 m and 5° of the truth."""
    for k, (est, truth) in enumerate(zip(estimates, poses)):
        if est.localised:
            d, turn = error(est, truth)
            assert d < 0.3 and turn < math.radians(5.0), (k, est, truth)


def room(cx: float, pillar: bool = False) -> list[np.ndarray]:
    """A 5 m × 4 m room centred at (cx, 0) with a cupboard in one corner (and a pillar)."""
    polys = [box_polygon(cx, 0.0, 5.0, 4.0), box_polygon(cx + 1.6, 1.3, 1.0, 0.6)]
    if pillar:
        polys.append(box_polygon(cx - 1.5, -1.2, 0.3, 0.3))
    return polys


def wander(cx: float, n: int = 50) -> list[tuple[float, float, float]]:
    """A small loop inside the room centred at (cx, 0)."""
    t = np.linspace(0.0, 1.5 * math.pi, n)
    return [(cx - 0.5 + 0.6 * math.cos(a), -0.2 + 0.5 * math.sin(a), a + math.pi / 2) for a in t]


def test_two_identical_rooms_stay_undecided() -> None:
    world = World.from_polygons(room(-4.0) + room(4.0))
    loc = Localizer(map_of(world, [(-4.5, -1.0), (3.5, -1.0)]))
    poses = wander(4.0)
    estimates = run(loc, world, poses)
    no_wrong_pose(estimates, poses)
    assert not any(e.localised for e in estimates)
    assert estimates[-1].state is LocalizerState.SEARCHING
    assert "ambiguous" in estimates[-1].reason


def test_a_difference_seen_decides_between_rooms() -> None:
    world = World.from_polygons(room(-4.0) + room(4.0, pillar=True))
    loc = Localizer(map_of(world, [(-4.5, -1.0), (3.5, -1.0)]))
    poses = wander(4.0)
    estimates = run(loc, world, poses, ROUND)
    no_wrong_pose(estimates, poses)
    assert estimates[-1].localised
    assert error(estimates[-1], poses[-1])[0] < 0.05


def corridor() -> World:
    """A 14 m × 2 m corridor, closed at both ends, with doorway recesses placed point-
    symmetrically: the same seen from either end."""
    polys = [box_polygon(0.0, 0.0, 14.0, 2.0)]
    for x, y in ((-3.0, 1.2), (3.0, -1.2), (-5.0, -1.2), (5.0, 1.2)):
        polys.append(box_polygon(x, y, 1.0, 0.4))
    return World.from_polygons(polys)


def test_a_corridor_alike_both_ways_stays_undecided() -> None:
    world = corridor()
    loc = Localizer(map_of(world, [(0.0, 0.0)]))
    poses = [(-1.0 + 0.04 * k, 0.1, 0.0) for k in range(50)]
    estimates = run(loc, world, poses, ROUND)
    no_wrong_pose(estimates, poses)
    assert not any(e.localised for e in estimates)
    assert estimates[-1].state is LocalizerState.SEARCHING


def office_path(n: int, start: float = -7.0, y: float = 0.0, heading: float = 0.0) -> list:
    """``n`` poses 0.1 m apart from (start, y) along ``heading``."""
    c, s = math.cos(heading), math.sin(heading)
    return [(start + 0.1 * k * c, y + 0.1 * k * s, heading) for k in range(n)]


def test_an_initial_pose_is_tracked_at_once() -> None:
    world = office()
    poses = office_path(30)
    loc = Localizer(
        map_of(world, [(0.0, 0.0)]), initial_pose=(poses[0][0] + 0.3, poses[0][1] - 0.2, 0.1)
    )
    estimates = run(loc, world, poses)
    assert all(e.localised for e in estimates)
    for est, truth in zip(estimates, poses):
        d, turn = error(est, truth)
        assert d < 0.05 and turn < math.radians(1.0)
        assert est.covariance is not None and np.all(np.linalg.eigvalsh(est.covariance) > 0)


def test_no_return_codes_and_invalid_readings_are_not_walls() -> None:
    """A scanner that reads "no return" as the SICK code 81.83 m (below its 81.9 m maximum,
    in the default no_return_bands), and NaN and inf: those beams are dropped, not taken
    for walls 81 m away, and it localises and tracks as well."""
    world = office()
    scanner = ScannerModel(n_beams=181, range_max=81.9, range_noise_std=0.01)
    loc = Localizer(map_of(world, [(0.0, 0.0)]))
    rng = np.random.default_rng(3)
    poses = office_path(40)
    estimates = []
    for k, pose in enumerate(poses):
        scan = simulate_scan(world, Pose2D(*pose), scanner, rng, stamp=0.1 * k, index=k)
        r = np.array(scan.ranges)
        r[k % 3 :: 3] = 81.83
        r[1::17], r[2::19] = np.nan, np.inf
        coded = scan.with_ranges(r)
        points = loc.points_of(coded)
        assert np.isfinite(points).all() and np.hypot(*points.T).max() < 25.0
        estimates.append(loc.update(coded, pose))
    no_wrong_pose(estimates, poses)
    assert estimates[-1].localised and error(estimates[-1], poses[-1])[0] < 0.05


def test_global_localisation_in_the_office_then_a_kidnapping() -> None:
    world = office()
    loc = Localizer(map_of(world, [(0.0, 0.0)]))
    first = office_path(60)
    later = office_path(60, start=6.0, heading=math.pi)
    # the odometry does not see the robot carried: its step at the jump is a normal one
    odometry = list(first)
    for k, pose in enumerate(later):
        step = relative(later[k - 1], pose) if k else np.array([0.1, 0.0, 0.0])
        odometry.append(tuple(compose(odometry[-1], step)))
    estimates = run(loc, world, first + later, ROUND, odometry)
    no_wrong_pose(estimates[:60], first)
    assert estimates[59].localised and error(estimates[59], first[-1])[0] < 0.05
    states = [e.state for e in estimates[60:]]
    assert LocalizerState.LOST in states[: loc.settings.lost_scans + 2]
    assert estimates[-1].localised and error(estimates[-1], later[-1])[0] < 0.05
    lost_at = states.index(LocalizerState.LOST)
    no_wrong_pose(estimates[60 + lost_at :], later[lost_at:])


def test_a_map_whose_origin_turns_gives_poses_in_its_frame() -> None:
    """The same cells with the origin's yaw 0.4 rad and another corner: the map frame turns
    with it, and so do the poses and covariances reported."""
    world = office()
    m = map_of(world, [(0.0, 0.0)])
    turned = OccupancyMap(m.cells, m.resolution, (2.0, -1.0, 0.4))
    move = compose(np.array(turned.origin), inverse(np.array(m.origin)))  # old frame → new
    poses = office_path(20)
    start = compose(move, poses[0])
    loc = Localizer(turned, initial_pose=tuple(start), initial_sigma=(0.2, 0.1))
    estimates = run(loc, world, poses)
    for est, truth in zip(estimates, poses):
        want = compose(move, truth)
        d, turn = error(est, tuple(want))
        assert d < 0.05 and turn < math.radians(1.0)
    # the covariance is the unturned map's, turned by the yaw
    plain = run(Localizer(m, initial_pose=poses[0], initial_sigma=(0.2, 0.1)), world, poses)
    c, s = math.cos(0.4), math.sin(0.4)
    r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    assert plain[-1].covariance is not None and estimates[-1].covariance is not None
    np.testing.assert_allclose(
        estimates[-1].covariance, r @ plain[-1].covariance @ r.T, rtol=0.3, atol=1e-6
    )


def test_scans_the_map_does_not_hold_make_it_lost() -> None:
    """Carried out of the mapped building (the scans are of another place): LOST within
    lost_scans scans, and no pose claimed afterwards."""
    world = office()
    loc = Localizer(map_of(world, [(0.0, 0.0)]), initial_pose=(-7.0, 0.0, 0.0))
    poses = office_path(10)
    assert all(e.localised for e in run(loc, world, poses))
    elsewhere = rectangular_room(3.0, 2.5)
    odometry = [tuple(compose(poses[-1], (0.1 * (k + 1), 0.0, 0.0))) for k in range(20)]
    away = [(0.0, 0.0, 0.05 * k) for k in range(20)]
    estimates = run(loc, elsewhere, away, ROUND, odometry)
    states = [e.state for e in estimates]
    assert states.index(LocalizerState.LOST) <= loc.settings.lost_scans
    assert not any(e.localised for e in estimates[loc.settings.lost_scans + 1 :])
    assert all(e.pose is None and e.covariance is None for e in estimates if not e.localised)
    assert "lost" in estimates[-1].reason


def test_set_initial_pose_mid_run_moves_the_estimate() -> None:
    world = office()
    loc = Localizer(map_of(world, [(0.0, 0.0)]))
    poses = office_path(20)
    run(loc, world, poses[:5])
    loc.set_initial_pose(Pose2D(*poses[5]), (0.2, 0.1))
    estimates = run(loc, world, poses[5:])
    assert estimates[0].localised
    no_wrong_pose(estimates, poses[5:])


@pytest.mark.parametrize("pose", [(100.0, 0.0, 0.0), (-50.0, -50.0, 1.0), (0.0, 5.8, 0.0)])
def test_an_impossible_initial_pose_raises(pose: tuple[float, float, float]) -> None:
    m = map_of(office(), [(0.0, 0.0)])
    with pytest.raises(InitialPoseError, match="initial pose") as info:
        Localizer(m, initial_pose=pose)
    assert isinstance(info.value, FuzzyposError) and isinstance(info.value, ValueError)
    assert f"{pose[0]:.3f}" in str(info.value)


def write_map(m: OccupancyMap, folder: Path) -> Path:
    from PIL import Image

    pixels = np.full(m.cells.shape, 205, dtype=np.uint8)
    pixels[m.cells == FREE] = 254
    pixels[m.cells == OCCUPIED] = 0
    Image.fromarray(pixels[::-1]).save(folder / "map.pgm")
    x, y, _ = m.origin
    yaml = folder / "map.yaml"
    yaml.write_text(
        f"image: map.pgm\nresolution: {m.resolution}\norigin: [{x}, {y}, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
        encoding="utf-8",
    )
    return yaml


def test_the_field_is_cached_beside_the_map(tmp_path: Path) -> None:
    yaml = write_map(map_of(office(), [(0.0, 0.0)]), tmp_path)
    first = Localizer(read_map_yaml(yaml))
    cache = Path(str(yaml) + CACHE_SUFFIX)
    assert cache.is_file()
    stamp = cache.stat().st_mtime_ns
    second = Localizer(read_map_yaml(yaml))
    assert cache.stat().st_mtime_ns == stamp  # read, not written again
    np.testing.assert_array_equal(first.field.walls.nearest, second.field.walls.nearest)
    # another map in the same place: the cache's key no longer matches, it is replaced
    yaml.write_text(yaml.read_text(encoding="utf-8").replace("resolution: 0.05", "resolution: 0.1"))
    third = Localizer(read_map_yaml(yaml))
    assert third.field.resolution == 0.1 and cache.stat().st_mtime_ns != stamp


def test_a_read_only_folder_is_no_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    yaml = write_map(map_of(office(), [(0.0, 0.0)]), tmp_path)

    def refuse(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", str(tmp_path))

    # the folder refuses new files (as a read-only one does, even to root here)
    monkeypatch.setattr(fuzzypos.localization.field.tempfile, "mkstemp", refuse)
    loc = Localizer(read_map_yaml(yaml))
    assert not Path(str(yaml) + CACHE_SUFFIX).exists()
    assert loc.state is LocalizerState.SEARCHING
    if os.name == "posix" and os.geteuid() != 0:  # a real read-only folder too
        monkeypatch.undo()
        tmp_path.chmod(0o555)
        try:
            Localizer(read_map_yaml(yaml))
            assert not Path(str(yaml) + CACHE_SUFFIX).exists()
        finally:
            tmp_path.chmod(0o755)


def test_the_config_section_round_trips() -> None:
    cfg = Config().with_overrides({"localization": {"evidence_margin": 20.0}})
    assert Config.from_dict(cfg.to_dict()).localization.evidence_margin == 20.0
    with pytest.raises(ValueError, match="localization"):
        Config().with_overrides({"localization": {"hit_sigma": -1.0}})
