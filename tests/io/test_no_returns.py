"""Scanner "no return" codes below ``range_max`` (``[scanner] no_return_bands``): the mask, the
features (a code is exactly an invalid reading), every log source, ``fuzzypos info``'s counts
and the configuration's validation."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from fuzzypos import sim
from fuzzypos.cli import app
from fuzzypos.config import Config, ConfigError, ScannerConfig
from fuzzypos.features import Features, extract_features
from fuzzypos.geometry import Pose2D
from fuzzypos.io import CarmenRecord, describe_log, open_log, write_carmen
from fuzzypos.io.logs import find_no_return_values
from fuzzypos.io.no_returns import FoundNoReturn, RangeTally, with_found_bands
from fuzzypos.jobs import run_log
from fuzzypos.scan import (
    NO_RETURN_SLACK,
    LaserScan,
    ScanError,
    no_return_counts,
    no_return_mask,
    usable,
)
from helpers import DATA, EXACT_SCANNER, make_bag

SICK = (81.83, 81.91)
#: the beams whose readings the tests replace by SICK codes, and the codes
CODED = (10, 11, 12, 47, 90, 91, 133, 170)
CODES = (81.83, 81.87, 81.83, 81.83, 81.87, 81.83, 81.87, 81.83)
#: the unshareable log's FLASER max_range: above the codes, so range_max keeps them valid
MAX_RANGE = 81.9


def no_bands() -> Config:
    return Config().with_overrides({"scanner": {"no_return_bands": ()}})


def room_scan(range_max: float = MAX_RANGE) -> LaserScan:
    """A scan of an 8 m × 6 m room from off the centre (every beam hits a wall, < 5 m)."""
    scan = sim.simulate_scan(sim.rectangular_room(), Pose2D(0.5, -0.3, 0.2), sim.ScannerModel())
    assert scan.valid.all() and scan.ranges.max() < 6.0
    return dataclasses.replace(scan, range_max=range_max)


def with_codes(scan: LaserScan, codes: Any = CODES) -> LaserScan:
    r = scan.ranges.copy()
    r[list(CODED)] = codes
    return scan.with_ranges(r)


def _arrays_of(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def assert_same_features(a: Features, b: Features) -> None:
    """Every stage's arrays equal, the lines and every kind of feature point too."""
    for name, value in _arrays_of(a).items():
        if name in ("lines", "_corners"):
            continue
        np.testing.assert_array_equal(value, getattr(b, name), err_msg=name)
    for name, value in _arrays_of(a.lines).items():
        np.testing.assert_array_equal(value, getattr(b.lines, name), err_msg=f"lines.{name}")
    for kind in ("angular_points", "virtual_points", "break_points", "points_of_interest"):
        pa, pb = getattr(a, kind), getattr(b, kind)
        for name, value in _arrays_of(pa).items():
            np.testing.assert_array_equal(value, getattr(pb, name), err_msg=f"{kind}.{name}")
    np.testing.assert_array_equal(a.virtual_lines, b.virtual_lines)


# -- the mask --------------------------------------------------------------------------------
def test_the_mask_on_known_readings() -> None:
    r = [1.0, 81.82, 81.83, 81.87, 81.91, 81.92, math.nan, math.inf, 0.0, 81.9]
    expect = [False, False, True, True, True, False, False, False, False, True]
    np.testing.assert_array_equal(no_return_mask(r, [SICK]), expect)
    assert not no_return_mask(r, []).any()
    # a band of zero width is one value; a second band adds its own
    np.testing.assert_array_equal(
        no_return_mask([5.0, 5.001, 4.999, 81.83, 81.87], [(5.0, 5.0), (81.83, 81.83)]),
        [True, False, False, True, False],
    )


def test_codes_stored_as_float32_still_match() -> None:
    # a ROS bag keeps float32: 81.91 becomes 81.9100037, 81.83 becomes 81.8300018
    r32 = np.array([81.83, 81.87, 81.91, 5.0], dtype=np.float32).astype(np.float64)
    assert r32[2] > 81.91
    np.testing.assert_array_equal(no_return_mask(r32, [SICK]), [True, True, True, False])
    np.testing.assert_array_equal(
        no_return_mask(r32[:1], [(81.83, 81.83)]), [True]
    )  # the exact value too
    # the slack is a float32 epsilon: a millimetre beyond the band is outside it
    assert not no_return_mask([81.911, 81.829], [SICK]).any()
    assert SICK[1] * NO_RETURN_SLACK < 1e-5


def test_counts_per_band_and_among() -> None:
    r = np.array([81.83, 81.85, 81.9, 3.0, 3.2, 81.83])
    bands = [(81.83, 81.86), (81.8, 81.95), (3.0, 3.0)]
    # 81.83, 81.85, 81.83 in the first; 81.9 only in the second (the first band wins overlaps)
    assert no_return_counts(r, bands) == [3, 1, 1]
    assert sum(no_return_counts(r, bands)) == int(no_return_mask(r, bands).sum())
    among = np.array([True, False, True, True, False, False])
    assert no_return_counts(r, bands, among=among) == [1, 1, 1]
    assert no_return_counts(r, []) == []


@pytest.mark.parametrize(
    "band,needle",
    [
        ((2.0, 1.0), "band 0 needs finite 0 <= low <= high"),
        ((math.nan, 1.0), "band 0 needs finite"),
        ((-1.0, 1.0), "band 0 needs finite 0 <= low"),
        ((1.0, math.inf), "band 0 needs finite"),
        ((1.0, 2.0, 3.0), "band 0 must be a (low, high) pair"),
    ],
)
def test_a_bad_band_in_code_is_a_scan_error(band: Any, needle: str) -> None:
    with pytest.raises(ScanError) as info:
        no_return_mask([1.0], [band])
    assert needle in str(info.value)
    assert isinstance(info.value, ValueError)


def test_usable_and_the_scans_points() -> None:
    scan = with_codes(room_scan())
    assert scan.valid.all()  # below range_max the codes are valid readings …
    keep = usable(scan, [SICK])
    assert np.flatnonzero(~keep).tolist() == list(CODED)  # … until the band drops them
    assert usable(scan, []) is scan.valid
    pts = scan.points_robot([SICK])
    assert np.isnan(pts[list(CODED)]).all() and not np.isnan(pts[keep]).any()
    assert not np.isnan(scan.points_robot()).any()  # without bands, as before


@settings(max_examples=200, deadline=None)
@given(
    ranges=st.lists(
        st.floats(min_value=0.0, max_value=120.0, allow_nan=False), min_size=1, max_size=60
    ),
    bands=st.lists(
        st.tuples(st.floats(0.0, 100.0), st.floats(0.0, 20.0)).map(lambda t: (t[0], t[0] + t[1])),
        max_size=4,
    ),
)
def test_readings_outside_every_band_are_never_dropped(
    ranges: list[float], bands: list[tuple[float, float]]
) -> None:
    r = np.array(ranges)
    mask = no_return_mask(r, bands)
    for x, dropped in zip(r, mask):
        inside = [lo <= x <= hi for lo, hi in bands]
        near = [lo * (1 - NO_RETURN_SLACK) <= x <= hi * (1 + NO_RETURN_SLACK) for lo, hi in bands]
        if any(inside):
            assert dropped, (x, bands)
        if not any(near):
            assert not dropped, (x, bands)
    scan = LaserScan(r, -1.0, 0.01, range_max=121.0)
    np.testing.assert_array_equal(usable(scan, bands), scan.valid & ~mask)


# -- the features ----------------------------------------------------------------------------
def test_codes_give_exactly_the_features_of_invalid_readings() -> None:
    clean = room_scan()
    coded = with_codes(clean)
    as_inf = with_codes(clean, math.inf)
    f_coded = extract_features(coded)  # the default configuration: SICK's band
    f_inf = extract_features(as_inf)
    assert f_inf.n_valid == clean.n_beams - len(CODED)
    assert set(f_coded.beam_index.tolist()).isdisjoint(CODED)
    assert_same_features(f_coded, f_inf)
    # not vacuous: without the band the codes are points 82 m away, the features differ
    f_raw = extract_features(coded, no_bands())
    assert f_raw.n_valid == clean.n_beams
    assert np.hypot(*f_raw.points.T).max() > 81.0
    with pytest.raises(AssertionError):
        assert_same_features(f_raw, f_inf)


def test_the_bands_come_from_the_config() -> None:
    scan = room_scan()
    lo, hi = 3.0, 3.5
    cfg = Config().with_overrides({"scanner": {"no_return_bands": ((lo, hi),)}})
    f = extract_features(scan, cfg)
    in_band = (scan.ranges >= lo) & (scan.ranges <= hi)
    assert 0 < in_band.sum() < scan.n_beams
    assert sorted(f.beam_index.tolist()) == np.flatnonzero(~in_band).tolist()
    assert not ((f.ranges >= lo) & (f.ranges <= hi)).any()
    # the default band lies beyond the room: nothing dropped
    assert extract_features(scan).n_valid == scan.n_beams


# -- every source alike ----------------------------------------------------------------------
def _num(v: float) -> str:
    return "inf" if v == math.inf else repr(float(v))


def write_flaser_log(path: Path, scans: list[LaserScan]) -> Path:
    """FLASER lines after ``PARAM robot_front_laser_max 81.9`` (the codes stay below it)."""
    lines = [f"PARAM robot_front_laser_max {MAX_RANGE!r} 0.0 host 0.0"]
    for k, s in enumerate(scans):
        r = " ".join(_num(v) for v in s.ranges)
        pose = f"{0.01 * k!r} 0.0 0.0"
        lines.append(f"FLASER {s.n_beams} {r} {pose} {pose} {s.stamp!r} host {s.stamp!r}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def write_robotlaser1_log(path: Path, scans: list[LaserScan]) -> Path:
    """ROBOTLASER1 lines carrying each scan's geometry and a max_range of 81.9."""
    lines = []
    for k, s in enumerate(scans):
        fields = [
            "ROBOTLASER1 0",
            repr(s.angle_min),
            repr(s.field_of_view),
            repr(s.angle_increment),
            repr(MAX_RANGE),
            "0.01 0",
            str(s.n_beams),
            *(_num(v) for v in s.ranges),
            "0",
            f"{0.01 * k!r} 0.0 0.0",  # the laser's pose
            f"{0.01 * k!r} 0.0 0.0",  # the robot's pose
            "0 0 0 0 0",
            repr(s.stamp),
            "host",
            repr(s.stamp),
        ]
        lines.append(" ".join(fields))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def coded_scans() -> list[LaserScan]:
    clean = room_scan()
    return [
        dataclasses.replace(with_codes(clean), stamp=1.0),
        dataclasses.replace(clean, stamp=2.0),
        dataclasses.replace(with_codes(clean, (81.83,) * len(CODED)), stamp=3.0),
    ]


def _bag(tmp_path: Path, kind: str) -> Path:
    scans = coded_scans()

    def build(b: Any) -> list[tuple[str, float, Any]]:
        return [("/scan", s.stamp + 0.005, b.scan(s.stamp, s.ranges, **geometry(s))) for s in scans]

    def geometry(s: LaserScan) -> dict[str, float]:
        a0, inc = s.angle_min, s.angle_increment
        amax = a0 + (s.n_beams - 1) * inc
        return {"angle_min": a0, "angle_max": amax, "angle_increment": inc, "range_max": 100.0}

    return make_bag(tmp_path, kind, build)


SOURCES = {
    "flaser": lambda tmp: write_flaser_log(tmp / "flaser.clf", coded_scans()),
    "robotlaser1": lambda tmp: write_robotlaser1_log(tmp / "rl1.clf", coded_scans()),
    "ros1": lambda tmp: _bag(tmp, "ros1"),
    "ros2": lambda tmp: _bag(tmp, "ros2-sqlite3"),
}


@pytest.mark.parametrize("source", sorted(SOURCES))
def test_every_source_drops_the_codes(tmp_path: Path, source: str) -> None:
    path = SOURCES[source](tmp_path)
    scans = [rec.scan for rec in open_log(path).records()]
    assert len(scans) == 3
    for k, scan in enumerate(scans):
        coded = np.zeros(scan.n_beams, bool)
        if k != 1:
            coded[list(CODED)] = True
        # below the log's range_max the codes are valid readings …
        assert scan.valid.all() and scan.range_max > max(CODES)
        np.testing.assert_array_equal(no_return_mask(scan.ranges, [SICK]), coded)
        # … and the features are those of the scan with them invalid
        f = extract_features(scan)
        assert set(f.beam_index.tolist()) == set(np.flatnonzero(~coded).tolist())
        assert_same_features(
            f, extract_features(scan.with_ranges(np.where(coded, 0.0, scan.ranges)))
        )
    info = describe_log(open_log(path))
    assert len(info.no_returns) == 1
    c = info.no_returns[0]
    assert (c.low_m, c.high_m) == SICK and c.removed == c.in_band == 2 * len(CODED)


# -- fuzzypos info ---------------------------------------------------------------------------
runner = CliRunner()


def _info(*args: str) -> Any:
    res = runner.invoke(app, ["info", *args])
    assert res.exit_code == 0, res.output
    return res


def test_info_reports_each_bands_readings(tmp_path: Path) -> None:
    path = write_flaser_log(tmp_path / "coded.clf", coded_scans())
    data = json.loads(_info(str(path), "--json").output)
    assert data["no_returns"] == [{"low_m": 81.83, "high_m": 81.91, "removed": 16, "in_band": 16}]
    text = _info(str(path)).output
    assert "no-return 81.83–81.91 m" in text and "16 readings removed" in text
    # the bands of --config: 81.83 alone, and a band no reading lies in
    cfg = tmp_path / "bands.toml"
    cfg.write_text("[scanner]\nno_return_bands = [[81.83, 81.83], [1.0, 1.1]]\n")
    data = json.loads(_info(str(path), "--json", "--config", str(cfg)).output)
    n_8183 = CODES.count(81.83) + len(CODED)
    assert [(c["low_m"], c["high_m"], c["removed"]) for c in data["no_returns"]] == [
        (81.83, 81.83, n_8183),
        (1.0, 1.1, 0),
    ]
    assert "no-return 81.83 m" in _info(str(path), "--config", str(cfg)).output


def test_info_counts_codes_already_invalid_at_range_max(tmp_path: Path) -> None:
    # without the PARAM line the reader learns range_max = 81.83 from the repeated code: those
    # readings are invalid already, only the 81.87 ones (above it, so valid) would be dropped
    path = write_flaser_log(tmp_path / "coded.clf", coded_scans())
    text = path.read_text().splitlines()[1:]
    path.write_text("\n".join(text) + "\n")
    c = describe_log(open_log(path)).no_returns[0]
    assert c.in_band == 16
    assert c.removed < c.in_band
    out = _info(str(path)).output
    assert f"{c.in_band - c.removed} more in the band already invalid at range_max" in out


def test_info_with_no_bands(tmp_path: Path) -> None:
    path = write_flaser_log(tmp_path / "coded.clf", coded_scans())
    cfg = tmp_path / "none.toml"
    cfg.write_text("[scanner]\nno_return_bands = []\n")
    assert json.loads(_info(str(path), "--json", "--config", str(cfg)).output)["no_returns"] == []
    assert "no-return bands" in _info(str(path), "--config", str(cfg)).output


# -- the configuration -----------------------------------------------------------------------
def test_the_default_band_and_its_declaration() -> None:
    assert Config().scanner == ScannerConfig(no_return_bands=(SICK,))
    spec = Config.schema()["scanner.no_return_bands"]
    assert spec.unit == "m" and spec.ge == 0.0 and "SICK" in spec.reason


@pytest.mark.parametrize(
    "bands",
    [(), ((81.83, 81.83),), ((81.83, 81.91), (50.0, 50.0), (0.0, 0.001))],
    ids=["none", "one value", "several"],
)
def test_bands_round_trip_through_toml(bands: tuple[tuple[float, float], ...]) -> None:
    cfg = Config().with_overrides({"scanner": {"no_return_bands": bands}})
    text = cfg.to_toml()
    back = Config.from_dict(tomllib.loads(text))
    assert back == cfg and back.scanner.no_return_bands == bands
    # and again onto a base whose bands are empty: the shape comes from the declaration
    assert Config.from_dict(tomllib.loads(text), base=no_bands()) == cfg
    assert Config.from_dict({"scanner": {"no_return_bands": [[1, 2]]}}, base=no_bands()) == (
        Config().with_overrides({"scanner": {"no_return_bands": ((1.0, 2.0),)}})
    )


@pytest.mark.parametrize(
    "text,needle",
    [
        ("no_return_bands = [[81.91, 81.83]]", r"scanner\.no_return_bands\[0\] needs low <= high"),
        (
            "no_return_bands = [[1, 2], [3, nan]]",
            r"scanner\.no_return_bands\[1\]\[1\] must be a fin",
        ),
        ("no_return_bands = [[inf, inf]]", r"scanner\.no_return_bands\[0\]\[0\] must be a finite"),
        ("no_return_bands = [[-1, 2]]", r"scanner\.no_return_bands\[0\]\[0\] must be >= 0"),
        ("no_return_bands = [[1, 2, 3]]", r"scanner\.no_return_bands: each band is \[low, high\]"),
        (
            "no_return_bands = [81.83, 81.91]",
            r"scanner\.no_return_bands: each band is \[low, high\]",
        ),
        ("no_return_bands = [['a', 2]]", r"scanner\.no_return_bands must be a number"),
        ("no_return_bands = 81.83", r"scanner\.no_return_bands must be a list"),
        ("no_return_band = []", r"unknown config key scanner\.no_return_band"),
    ],
)
def test_bad_bands_from_a_file_name_the_file_and_key(
    tmp_path: Path, text: str, needle: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(f"[scanner]\n{text}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=rf"{re.escape(str(path))}: {needle}"):
        Config.from_toml(path)


@pytest.mark.parametrize(
    "bands,needle",
    [
        (((2.0, 1.0),), r"scanner\.no_return_bands\[0\] needs low <= high"),
        (((1.0, 2.0), (math.nan, 1.0)), r"scanner\.no_return_bands\[1\]\[0\] must be a finite"),
        (((1.0, 2.0, 3.0),), r"scanner\.no_return_bands\[0\] must be a \[low, high\] pair"),
        ((81.83, 81.91), r"scanner\.no_return_bands\[0\] must be a \[low, high\] pair"),
    ],
)
def test_bad_bands_in_code_are_config_errors(bands: Any, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        Config().with_overrides({"scanner": {"no_return_bands": bands}})


# -- codes found in the data (``[scanner] find_no_return_values``) ------------------------------
#: the held-back logs' scanner: "no return" read as 50.0 m or 51.14 m, below a 51.16 m maximum
HELD_BACK_CODES = (50.0, 51.14)
HELD_BACK_MAX = 51.16


def coded_run(seed: int = 3) -> tuple[sim.SimulatedRun, list[LaserScan]]:
    """A lap in the furnished room whose scanner reads "no return" (8 % of the beams drop out)
    as 50.0 m or 51.14 m at random, below its range_max of 51.16 m; the room's walls are all
    within 8 m. Ranges noisy (1 cm), so a wall's readings rarely repeat exactly."""
    scanner = sim.ScannerModel(
        range_max=HELD_BACK_MAX,
        no_return_value=HELD_BACK_CODES[0],
        dropout_probability=0.08,
        range_noise_std=0.01,
        rate_hz=5.0,
    )
    path = sim.CommandedPath.circle(1.0, laps=1.0, speed=0.3)
    run = sim.simulate_run(sim.furnished_room(), path, scanner, sim.SlipModel(), seed)
    rng = np.random.default_rng(seed)
    scans = []
    for s in run.scans:
        r = s.ranges.copy()
        r[(r == HELD_BACK_CODES[0]) & (rng.random(r.size) < 0.5)] = HELD_BACK_CODES[1]
        scans.append(s.with_ranges(r))
    return run, scans


def write_run(path: Path, run: sim.SimulatedRun, scans: list[LaserScan]) -> Path:
    records = (CarmenRecord(s, run.odometry_pose(k), run.true_pose(k)) for k, s in enumerate(scans))
    write_carmen(path, records)
    return path


def coded_counts(scans: list[LaserScan]) -> dict[float, int]:
    return {v: sum(int((s.ranges == v).sum()) for s in scans) for v in HELD_BACK_CODES}


def with_scanner(**fields: Any) -> ScannerConfig:
    return dataclasses.replace(ScannerConfig(), **fields)


def test_codes_below_range_max_are_found_and_dropped(tmp_path: Path) -> None:
    run, scans = coded_run()
    path = write_run(tmp_path / "coded.clf", run, scans)
    counts = coded_counts(scans)
    log = open_log(path)
    read = [rec.scan for rec in log.records()]
    # below the log's range_max the codes are valid readings: without the feature, walls
    assert all(s.range_max == HELD_BACK_MAX for s in read)
    assert sum(int((s.valid & (s.ranges >= 50.0)).sum()) for s in read) == sum(counts.values())
    found = find_no_return_values(log, ScannerConfig())
    assert [(f.value_m, f.readings) for f in found] == [
        (v, counts[v]) for v in sorted(HELD_BACK_CODES, reverse=True)
    ]
    assert all(f.invalid_at_range_max == 0 and not f.in_configured_band for f in found)
    # the run's configuration drops them, and the features are those of invalid readings
    cfg = with_found_bands(Config(), found)
    assert cfg.scanner.no_return_bands[0] == SICK and len(cfg.scanner.no_return_bands) == 3
    for scan in read[:20]:
        coded = np.isin(np.round(scan.ranges, 4), HELD_BACK_CODES)
        f = extract_features(scan, cfg)
        assert set(f.beam_index.tolist()).isdisjoint(np.flatnonzero(coded).tolist())
        assert np.hypot(*f.points.T).max() < 20.0
        assert_same_features(
            f, extract_features(scan.with_ranges(np.where(coded, 0.0, scan.ranges)), cfg)
        )
    # not vacuous: the configured bands alone keep them as points 50 m away
    assert max(np.hypot(*extract_features(s).points.T).max() for s in read[:20]) > 49.0
    # switched off, nothing is looked for
    assert find_no_return_values(log, with_scanner(find_no_return_values=False)) == []


def test_a_code_below_the_inferred_maximum_is_found(tmp_path: Path) -> None:
    # without the PARAM line the reader infers range_max from the repeated top code (51.14 m),
    # which leaves the other (50.0 m) valid: found, and the only one that needs a band
    run, scans = coded_run()
    path = write_run(tmp_path / "coded.clf", run, scans)
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(ln for ln in lines if not ln.startswith("PARAM robot_front_laser_max")))
    log = open_log(path)
    assert {rec.scan.range_max for rec in log.records()} == {51.14}
    counts = coded_counts(scans)
    found = find_no_return_values(log, ScannerConfig())
    assert [(f.value_m, f.readings, f.invalid_at_range_max) for f in found] == [
        (51.14, counts[51.14], counts[51.14]),
        (50.0, counts[50.0], 0),
    ]
    assert with_found_bands(Config(), found).scanner.no_return_bands == (SICK, found[1].band)


def test_info_lists_the_codes_found(tmp_path: Path) -> None:
    run, scans = coded_run()
    path = write_run(tmp_path / "coded.clf", run, scans)
    counts = coded_counts(scans)
    data = json.loads(_info(str(path), "--json").output)
    assert [(f["value_m"], f["readings"]) for f in data["no_return_values_found"]] == [
        (51.14, counts[51.14]),
        (50.0, counts[50.0]),
    ]
    text = _info(str(path)).output
    for v in HELD_BACK_CODES:
        assert f"no-return {v:g} m (found in the data)" in text
        assert f"{counts[v]:,} readings" in text
    cfg = tmp_path / "off.toml"
    cfg.write_text("[scanner]\nfind_no_return_values = false\n")
    data = json.loads(_info(str(path), "--json", "--config", str(cfg)).output)
    assert data["no_return_values_found"] == []
    assert "not looked for" in _info(str(path), "--config", str(cfg)).output


def test_a_run_adds_the_codes_to_its_bands(tmp_path: Path) -> None:
    run, scans = coded_run()
    path = write_run(tmp_path / "coded.clf", run, scans)
    res = run_log(path, results_dir=tmp_path / "out", max_scans=8, plot=False, hash_input=False)
    found = res.summary["no_return_values_found"]
    assert [f["value_m"] for f in found] == [51.14, 50.0]  # from the whole log, not the 8 scans
    assert [f["readings"] for f in found] == [coded_counts(scans)[v] for v in (51.14, 50.0)]
    back = Config.from_toml(res.files["config.toml"])
    bands = back.scanner.no_return_bands
    assert bands[0] == SICK and len(bands) == 3
    assert no_return_mask(list(HELD_BACK_CODES), bands).all()
    assert not no_return_mask([49.999, 50.001, 51.139, 51.141], bands).any()
    # the configuration written finds them again, already in its bands: nothing is added twice
    log = open_log(path)
    again = find_no_return_values(log, back.scanner)
    assert all(f.in_configured_band for f in again) and len(again) == 2
    assert with_found_bands(back, again) is back
    # nor is a band added for a code range_max already makes invalid (a ROS-style maximum)
    at_max = FoundNoReturn(30.0, readings=500, invalid_at_range_max=500)
    assert with_found_bands(Config(), [at_max]) == Config()
    assert with_found_bands(Config(), [dataclasses.replace(at_max, invalid_at_range_max=499)]) != (
        Config()
    )


def still_run() -> sim.SimulatedRun:
    """Half a lap, then standing still three times as long, with a noise-free scanner: every
    beam repeats its exact range scan after scan, walls up to 7.5 m away."""
    scanner = sim.ScannerModel(**EXACT_SCANNER, range_max=30.0, rate_hz=5.0)
    path = sim.CommandedPath.circle(1.0, laps=0.5, speed=0.3)
    return sim.simulate_run(
        sim.furnished_room(), path, scanner, sim.SlipModel(), 1, duration=4 * path.duration
    )


def test_a_wall_seen_while_standing_still_is_no_code(tmp_path: Path) -> None:
    run = still_run()
    path = write_run(tmp_path / "still.clf", run, run.scans)
    still = run.scans[-1].ranges
    assert all(np.array_equal(s.ranges, still) for s in run.scans[-100:])
    log = open_log(path)
    assert find_no_return_values(log, ScannerConfig()) == []
    # not vacuous: it is the moving share that tells (the far walls' exact values lie at the
    # top, with no neighbours within 5 cm, repeated in hundreds of readings)
    taken = find_no_return_values(log, with_scanner(find_moving_share=0.0))
    assert taken and all(f.readings >= 100 for f in taken)
    assert set(np.round([f.value_m for f in taken], 3)) <= set(np.round(still, 3))
    assert describe_log(log).no_return_values_found == []


def test_an_ordinary_repeated_range_is_no_spike() -> None:
    """Ranges quantised to 1 cm over 0.5-8 m repeat each in hundreds of readings while the robot
    moves; a code above them stands out, a value in their midst does not, however often."""
    rng = np.random.default_rng(5)

    def tally(extra: dict[float, int]) -> RangeTally:
        t = RangeTally()
        for k in range(1000):
            r = np.round(rng.uniform(0.5, 8.0, 180), 2)
            beams = iter(rng.permutation(180))
            for v, n in extra.items():
                r[[next(beams) for _ in range(n)]] = v
            t.add(LaserScan(r, -1.5, 0.0167, range_max=100.0), odometry=k)
        return t

    plain = tally({})
    assert plain.readings == 180_000
    assert (plain.total >= 200).sum() > 100  # every value repeats in hundreds of readings
    assert plain.find(ScannerConfig()) == []
    found = tally({60.0: 2, 5.0: 4}).find(ScannerConfig())
    assert [(f.value_m, f.readings) for f in found] == [(60.0, 2000)]
    # 5.0 m in 4,000 readings more than its neighbours: the top test (b) rejects it ...
    spiked = tally({5.0: 4})
    at_top = spiked.find(with_scanner(find_top_fraction=1.0))
    assert [f.value_m for f in at_top] == [5.0] and at_top[0].readings > 4000
    # ... and at 1,000 more the neighbourhood (c) too, the top test dropped
    assert tally({5.0: 1}).find(with_scanner(find_top_fraction=1.0)) == []


def test_explicit_bands_still_apply(tmp_path: Path) -> None:
    run, scans = coded_run()
    path = write_run(tmp_path / "coded.clf", run, scans)
    counts = coded_counts(scans)
    # a configured band that holds 50.0 m: found, but not added again
    scanner = with_scanner(no_return_bands=((50.0, 50.0),))
    found = find_no_return_values(open_log(path), scanner)
    assert [(f.value_m, f.in_configured_band) for f in found] == [(51.14, False), (50.0, True)]
    cfg = with_found_bands(
        Config().with_overrides({"scanner": {"no_return_bands": ((50.0, 50.0),)}}), found
    )
    assert cfg.scanner.no_return_bands[0] == (50.0, 50.0) and len(cfg.scanner.no_return_bands) == 2
    # with the finding off, the bands given are all there is
    info = describe_log(
        open_log(path),
        scanner=with_scanner(no_return_bands=((50.0, 50.0),), find_no_return_values=False),
    )
    assert info.no_return_values_found == []
    assert [(c.removed) for c in info.no_returns] == [counts[50.0]]


def test_a_bag_input_too(tmp_path: Path) -> None:
    run, scans = coded_run()
    counts = coded_counts(scans)

    def build(b: Any) -> list[tuple[str, float, Any]]:
        msgs = []
        for k, s in enumerate(scans):
            a0, inc = s.angle_min, s.angle_increment
            geometry = {
                "angle_min": a0,
                "angle_max": a0 + (s.n_beams - 1) * inc,
                "angle_increment": inc,
                "range_max": HELD_BACK_MAX,
            }
            msgs.append(("/scan", s.stamp + 0.005, b.scan(s.stamp, s.ranges, **geometry)))
            msgs.append(("/odom", s.stamp + 0.004, b.odom(s.stamp, run.odometry_poses[k])))
        msgs.sort(key=lambda m: m[1])
        return msgs

    path = make_bag(tmp_path, "ros1", build)
    log = open_log(path)
    found = find_no_return_values(log, ScannerConfig())
    # float32 in the bag: 51.14 is 51.1399994, still one value repeated, found to 0.1 mm
    assert [(f.value_m, f.readings) for f in found] == [
        (51.14, counts[51.14]),
        (50.0, counts[50.0]),
    ]
    scan = next(iter(log.records())).scan
    bands = with_found_bands(Config(), found).scanner.no_return_bands
    coded = np.isin(np.round(scan.ranges, 4), HELD_BACK_CODES)
    assert coded.any()
    np.testing.assert_array_equal(no_return_mask(scan.ranges, bands), coded)


#: the shared logs' "no return" codes as their README gives them: value (m) -> readings
KNOWN_CODES = {
    "intel/intel.clf.gz": {81.83: 68_313},
    "aces/aces.clf.gz": {50.0: 11_139},
    "aces/aces.bag": {50.0: 11_139},
    "fr-clinic/fr-clinic.clf.gz": {81.83: 5_849},
}


@pytest.mark.parametrize("name", sorted(KNOWN_CODES))
def test_the_shared_logs_known_codes_and_nothing_near_the_walls(name: str) -> None:
    path = DATA / name
    if not path.exists():
        pytest.skip(f"the shared logs are not in {DATA} (see its README.md; CI has them)")
    found = {f.value_m: f.readings for f in find_no_return_values(open_log(path), ScannerConfig())}
    assert KNOWN_CODES[name].items() <= found.items()
    # anything else found is a SICK code too (fr-clinic's 81.91 m, at its range_max)
    assert all(v >= 50.0 for v in found), found
