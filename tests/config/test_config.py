"""Tests of the configuration: TOML round trip, degrees at the edge, errors that name the key."""

from __future__ import annotations

import math
import re
import sys
import warnings
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner, Result

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from fuzzypos.config import (
    PRESETS,
    Config,
    ConfigError,
    FilterConfig,
    FuzzyConfig,
    MatchingConfig,
    OdometryConfig,
    RefinementConfig,
    SearchConfig,
)

# the angle fields: (section, field) -> default in degrees
ANGLES_DEG = {
    ("filtering", "detection_angle_threshold"): 22.5,
    ("angular_points", "interior_angle_threshold"): 135.0,
    ("virtual_points", "min_intersection_angle"): 30.0,
    ("matching", "keyframe_angle"): 30.0,
    ("matching", "line_angle_gate"): 3.0,
    ("matching", "line_angle_gate_prior"): 8.0,
    ("matching", "line_trim_angle"): 0.2,
    ("refinement", "prior_sigma_angle"): 2.0,
    ("refinement", "max_bend_angle"): 30.0,
    ("refinement", "both_angle"): 1.0,
    ("odometry", "max_jump_angle"): 20.0,
    ("search", "angle"): 180.0,
    ("search", "angle_step"): 2.0,
    ("search", "failure_angle"): 30.0,
    ("refinement", "converged_rotation"): math.degrees(1e-5),
    ("matching", "line_consensus_angle"): math.degrees(math.asin(0.342)),
    ("covariance", "floor_rotation"): 0.01,
    ("covariance", "feature_rotation"): 0.5,
    ("covariance", "no_odometry_rotation"): 30.0,
    ("odometry_noise", "rotation_per_sqrt_m"): 0.2,
    ("odometry_noise", "floor_rotation"): 0.05,
    ("odometry_noise", "min_rotation_per_sqrt_m"): 0.05,
    ("odometry_noise", "max_rotation_per_sqrt_m"): 20.0,
    ("loop_closure", "search_angle"): 20.0,
    ("loop_closure", "heading_floor"): 4.0,
    ("loop_closure", "closure_floor_rotation"): 2.0,
    ("loop_closure", "map_scan_angle"): 10.0,
    ("localization", "separation_angle"): 20.0,
    ("localization", "odometry_rotation"): 3.0,
    ("localization", "covariance_floor_rotation"): 0.5,
    ("localization", "initial_sigma_rotation"): 15.0,
}
ANGLE_WORDS = ("angle", "rotation", "heading", "bearing", "yaw", "theta")
SECTIONS = [
    "fuzzy",
    "filtering",
    "segmentation",
    "angular_points",
    "lines",
    "virtual_points",
    "matching",
    "fusion",
    "refinement",
    "odometry",
    "search",
    "covariance",
    "odometry_noise",
    "gate",
    "scanner",
    "loop_closure",
    "localization",
]


def load(text: str, base: Config | None = None) -> Config:
    return Config.from_dict(tomllib.loads(text), base=base)


# ---------------------------------------------------------------------------------------------
# Round trip
# ---------------------------------------------------------------------------------------------
def test_config_error_is_a_value_error() -> None:
    assert issubclass(ConfigError, ValueError)


def test_default_round_trips_through_toml() -> None:
    cfg = Config()
    text = cfg.to_toml()
    back = Config.from_dict(tomllib.loads(text))
    assert back == cfg
    assert back.to_toml() == text


def test_every_field_is_written() -> None:
    data = tomllib.loads(Config().to_toml())
    assert sorted(data) == sorted(SECTIONS)
    for sec in SECTIONS:
        cls = type(getattr(Config(), sec))
        keys = set()
        for f in fields(cls):
            keys.add(
                f.name + "_deg"
                if (sec, f.name) in ANGLES_DEG or f.name == "detection_angle_sets"
                else f.name
            )
        assert set(data[sec]) == keys, sec


def test_round_trip_is_not_vacuous() -> None:
    # a changed value survives the trip, and loading onto the default base keeps the change
    cfg = Config().with_overrides(
        {
            "matching": {"pairing_distance": 0.37, "mutual": False},
            "filtering": {"detection_angle_threshold": math.radians(17.0)},
            "fuzzy": {"point_rules": ("SSS", "MSS", "BMM", "BBM", "BBB")},
        }
    )
    back = Config.from_dict(tomllib.loads(cfg.to_toml()))
    assert back == cfg
    assert back != Config()
    assert back.matching.pairing_distance == 0.37
    assert back.fuzzy.point_rules[0] == "SSS"


@pytest.mark.parametrize("name", ["default", "paper"])
def test_presets_round_trip(name: str) -> None:
    cfg = Config.preset(name)
    # onto the default base: every key is written, so the base does not matter
    assert Config.from_dict(tomllib.loads(cfg.to_toml())) == cfg


def test_dump_and_from_toml(tmp_path: Path) -> None:
    cfg = Config.preset("paper")
    path = tmp_path / "paper.toml"
    cfg.dump(path)
    assert Config.from_toml(path) == cfg


def test_empty_mapping_is_the_base() -> None:
    assert Config.from_dict({}) == Config()
    paper = Config.preset("paper")
    assert Config.from_dict({}, base=paper) == paper


# ---------------------------------------------------------------------------------------------
# Degrees at the edge
# ---------------------------------------------------------------------------------------------
def test_angles_are_degrees_under_deg_keys() -> None:
    data = tomllib.loads(Config().to_toml())
    assert data["filtering"]["detection_angle_threshold_deg"] == 22.5
    assert "detection_angle_threshold" not in data["filtering"]
    for (sec, name), deg in ANGLES_DEG.items():
        assert data[sec][name + "_deg"] == pytest.approx(deg, abs=1e-9), (sec, name)
        assert name not in data[sec]
    assert data["fuzzy"]["detection_angle_sets_deg"] == [[0, 0, 45], [0, 45, 90], [45, 90, 90]]
    assert "detection_angle_sets" not in data["fuzzy"]
    # non-angles are not converted
    assert data["matching"]["pairing_distance"] == Config().matching.pairing_distance
    assert data["fuzzy"]["distance_sets"][-1] == [6.0, 8.0, 8.0]


def test_every_angle_field_is_written_in_degrees() -> None:
    # any field named like an angle (now or added later) must sit under a _deg key, and its
    # degree value must load back to the same radians
    cfg = Config()
    data = tomllib.loads(cfg.to_toml())
    found = 0
    for sec in SECTIONS:
        for f in fields(getattr(cfg, sec)):
            if not any(w in f.name for w in ANGLE_WORDS):
                continue
            found += 1
            assert f.name + "_deg" in data[sec] and f.name not in data[sec], f"{sec}.{f.name}"
            value = getattr(getattr(cfg, sec), f.name)
            deg = data[sec][f.name + "_deg"]
            if isinstance(value, float):
                assert math.radians(deg) == pytest.approx(value, abs=1e-15)
    assert found >= len(ANGLES_DEG) + 1


def test_defaults_are_radians_in_code() -> None:
    cfg = Config()
    assert cfg.filtering.detection_angle_threshold == pytest.approx(math.pi / 8)
    assert cfg.angular_points.interior_angle_threshold == pytest.approx(3 * math.pi / 4)
    assert cfg.fuzzy.detection_angle_sets[-1] == pytest.approx(
        (math.pi / 4, math.pi / 2, math.pi / 2)
    )


def test_deg_keys_load_as_radians() -> None:
    cfg = load(
        """
        [filtering]
        detection_angle_threshold_deg = 30
        [angular_points]
        interior_angle_threshold_deg = 120.0
        [fuzzy]
        detection_angle_sets_deg = [[0, 0, 30], [0, 30, 90], [30, 90, 90]]
        """
    )
    assert cfg.filtering.detection_angle_threshold == pytest.approx(math.radians(30))
    assert isinstance(cfg.filtering.detection_angle_threshold, float)
    assert cfg.angular_points.interior_angle_threshold == pytest.approx(math.radians(120))
    r30, r90 = math.radians(30), math.radians(90)
    expected_sets = [(0.0, 0.0, r30), (0.0, r30, r90), (r30, r90, r90)]
    assert len(cfg.fuzzy.detection_angle_sets) == 3
    for got, want in zip(cfg.fuzzy.detection_angle_sets, expected_sets):
        assert isinstance(got, tuple) and got == pytest.approx(want, abs=1e-15)
    # untouched sections keep the base
    assert cfg.matching == Config().matching


@pytest.mark.parametrize(
    "section,key",
    [
        ("filtering", "detection_angle_threshold"),
        ("angular_points", "interior_angle_threshold"),
        ("virtual_points", "min_intersection_angle"),
        ("fuzzy", "detection_angle_sets"),
    ],
)
def test_angle_without_deg_is_an_error(section: str, key: str) -> None:
    value = "[[0, 0, 1], [0, 1, 1.5], [1, 1.5, 1.5]]" if key == "detection_angle_sets" else "0.5"
    with pytest.raises(ConfigError, match=rf"{section}\.{key}") as info:
        load(f"[{section}]\n{key} = {value}\n")
    assert f"{key}_deg" in str(info.value)  # the message says what to write instead


def test_deg_suffix_on_a_non_angle_is_an_error() -> None:
    with pytest.raises(ConfigError, match="pairing_distance_deg"):
        load("[matching]\npairing_distance_deg = 1\n")


# ---------------------------------------------------------------------------------------------
# Unknown keys and sections, wrong types
# ---------------------------------------------------------------------------------------------
def test_unknown_key_is_an_error_naming_it() -> None:
    with pytest.raises(ConfigError, match="pairing_distanse") as info:
        load("[matching]\npairing_distanse = 1\n")
    assert isinstance(info.value, ValueError)
    assert "matching" in str(info.value)


def test_unknown_section_is_an_error_naming_it() -> None:
    with pytest.raises(ConfigError, match="matchin"):
        load("[matchin]\npairing_distance = 1\n")
    with pytest.raises(ConfigError, match="bogus"):
        load("bogus = 3\n")


def test_section_must_be_a_table() -> None:
    with pytest.raises(ConfigError, match="matching"):
        load("matching = 3\n")


def test_with_overrides_rejects_unknown_keys() -> None:
    with pytest.raises(ConfigError, match="pairing_distanse"):
        Config().with_overrides({"matching": {"pairing_distanse": 1.0}})
    with pytest.raises(ConfigError, match="matchin"):
        Config().with_overrides({"matchin": {"pairing_distance": 1.0}})


@pytest.mark.parametrize(
    "text,key",
    [
        (
            '[matching]\npairing_distance = "0.5"\n',
            "matching.pairing_distance",
        ),  # string for a float
        ("[lines]\nmin_points = 4.0\n", "lines.min_points"),  # float for an int
        ("[matching]\npairing_distance = true\n", "matching.pairing_distance"),  # bool for a float
        ("[lines]\nmin_points = true\n", "lines.min_points"),  # bool for an int
        ("[matching]\nmutual = 1\n", "matching.mutual"),  # int for a bool
        ("[fusion]\nmethod = 3\n", "fusion.method"),  # int for a string
        (
            '[filtering]\ndetection_angle_threshold_deg = "22.5"\n',
            "filtering.detection_angle_threshold_deg",
        ),
        ('[fuzzy]\npoint_rules = "MSS"\n', "fuzzy.point_rules"),  # string for a list
        ("[fuzzy]\npoint_rules = [1, 2, 3, 4, 5]\n", "fuzzy.point_rules"),
        ("[fuzzy]\ndistance_sets = [[0, 0], [0, 2, 4]]\n", "fuzzy.distance_sets"),
        ('[fuzzy]\ndistance_sets = [[0, 0, "2"]]\n', "fuzzy.distance_sets"),
        ("[fuzzy]\noutput_centres = [0, true, 1]\n", "fuzzy.output_centres"),
    ],
)
def test_wrong_types_are_errors_naming_the_key(text: str, key: str) -> None:
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load(text)


def test_int_is_accepted_for_a_float_and_stored_as_float() -> None:
    cfg = load("[matching]\npairing_distance = 1\n")
    assert cfg.matching.pairing_distance == 1.0
    assert type(cfg.matching.pairing_distance) is float


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------
def test_from_toml_with_preset_and_override(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text(
        'preset = "paper"\n\n[matching]\npairing_distance = 0.7\n\n'
        "[filtering]\ndetection_angle_threshold_deg = 25.0\n",
        encoding="utf-8",
    )
    cfg = Config.from_toml(path)
    paper = Config.preset("paper")
    assert cfg.matching.pairing_distance == 0.7
    assert cfg.filtering.detection_angle_threshold == pytest.approx(math.radians(25.0))
    # everything else is the paper preset, not the default
    assert cfg.fusion == paper.fusion
    assert cfg.fusion.method == "weighted_mean"
    assert cfg.matching.mutual is False
    assert cfg == paper.with_overrides(
        {
            "matching": {"pairing_distance": 0.7},
            "filtering": {"detection_angle_threshold": math.radians(25.0)},
        }
    )


def test_from_toml_without_preset_is_the_default_base(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text("[matching]\npairing_distance = 0.7\n", encoding="utf-8")
    assert Config.from_toml(str(path)) == Config().with_overrides(
        {"matching": {"pairing_distance": 0.7}}
    )


def test_from_toml_unknown_preset(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text('preset = "papr"\n', encoding="utf-8")
    with pytest.raises(ConfigError, match="papr"):
        Config.from_toml(path)
    path.write_text("preset = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="preset"):
        Config.from_toml(path)


def test_from_toml_errors_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[matching]\npairing_distanse = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        Config.from_toml(path)
    assert str(path) in str(info.value) and "pairing_distanse" in str(info.value)


def test_missing_file_names_the_path(tmp_path: Path) -> None:
    path = tmp_path / "nowhere" / "missing.toml"
    with pytest.raises(ConfigError) as info:
        Config.from_toml(path)
    assert str(path) in str(info.value)


def test_invalid_toml_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text("[matching\npairing_distance = = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        Config.from_toml(path)
    assert str(path) in str(info.value)
    assert "TOML" in str(info.value)


def test_a_file_that_is_not_utf8_names_the_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes("# réglages\n[odometry]\n# é\n".encode("latin-1"))
    with pytest.raises(ConfigError) as info:
        Config.from_toml(path)
    assert str(info.value) == (
        f"{path}:1: not UTF-8 text (TOML files are UTF-8): byte 0xe9 at offset 3"
    )


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("[odometry]\nmax_speed = 1" + "0" * 400, "odometry.max_speed"),  # a float setting
        ("[refinement]\niterations = 1" + "0" * 400, "refinement.iterations"),  # an integer
        ("[scanner]\nno_return_bands = [[1, 1" + "0" * 400 + "]]", "scanner.no_return_bands"),
        ("[filtering]\ndetection_angle_threshold_deg = 1" + "0" * 400, "filtering.detection"),
    ],
)
def test_a_number_too_big_for_a_float_is_a_config_error(
    tmp_path: Path, text: str, key: str
) -> None:
    path = tmp_path / "big.toml"
    path.write_text(text + "\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=rf"big\.toml: {key}.* too large: an integer of 401"):
        Config.from_toml(path)


def test_arrays_nested_too_deeply_are_a_config_error(tmp_path: Path) -> None:
    path = tmp_path / "deep.toml"
    path.write_text("[scanner]\nno_return_bands = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ConfigError, match=r"deep\.toml: invalid TOML: .* nested too deeply"):
        Config.from_toml(path)


# ---------------------------------------------------------------------------------------------
# Presets
# ---------------------------------------------------------------------------------------------
def _flat(cfg: Config) -> dict[str, object]:
    return {
        f"{sec}.{f.name}": getattr(getattr(cfg, sec), f.name)
        for sec in SECTIONS
        for f in fields(getattr(cfg, sec))
    }


def test_paper_preset_differs_in_the_documented_ways() -> None:
    default, paper = _flat(Config()), _flat(Config.preset("paper"))
    differ = {k: (default[k], paper[k]) for k in default if default[k] != paper[k]}
    # the paper preset changes exactly what PRESETS["paper"] lists, nothing else ...
    listed = {f"{sec}.{k}" for sec, vals in PRESETS["paper"].items() for k in vals}
    assert set(differ) <= listed
    # ... never the fuzzy systems (Tables 1–3, eq. 4) or ξ_TH
    assert not [k for k in differ if k.startswith(("fuzzy.", "filtering."))]
    # and at least these, each a stage the paper does not have
    expected = {
        # SPEC step 5: refinement to the lines' intersection is ours
        "angular_points.refine": (True, False),
        # §3.7: any feature point pairs with the one point within T; no kind or mutual check
        "matching.same_kind_only": (True, False),
        "matching.mutual": (True, False),
        "matching.use_break_points": (False, True),
        # line-to-line matching and unrefined-corner handling are ours
        "matching.match_lines": (True, False),
        "angular_points.pair_unrefined": (False, True),
        # eq. 23–24: the weighted mean of the two-pair solutions, no outlier rejection
        "fusion.method": ("least_squares", "weighted_mean"),
        "fusion.robust": (True, False),
    }
    assert {k: differ.get(k) for k in expected} == expected


def test_paper_preset_keeps_the_papers_values() -> None:
    paper = Config.preset("paper")
    assert math.degrees(paper.filtering.detection_angle_threshold) == pytest.approx(22.5, abs=1e-12)
    assert paper.fuzzy.point_rules == ("MSS", "MSS", "BMM", "BBM", "BBB")  # Table 1
    assert paper.fuzzy.line_rules == ("SSM", "SMB", "MBB")  # Table 2
    assert paper.fuzzy.virtual_pair_rules == ("SSM", "SMB", "MBB")  # Table 3 upper
    assert paper.fuzzy.virtual_distance_rules == ("SSM", "SSM", "SMB", "MBB", "BBB")  # lower
    assert paper.fuzzy.inference == "product"  # eq. 4
    assert paper.lines.min_points == 4  # §5
    assert paper.matching.use_angular_points and paper.matching.use_virtual_points


def test_default_preset_is_the_default() -> None:
    assert Config.preset("default") == Config()
    assert PRESETS["default"] == {}


def test_unknown_preset_raises() -> None:
    with pytest.raises(ConfigError, match="fancy"):
        Config.preset("fancy")


def test_every_preset_is_valid_and_known_keys_only() -> None:
    for name, overrides in PRESETS.items():
        Config.preset(name)
        for sec, values in overrides.items():
            assert sec in SECTIONS
            known = {f.name for f in fields(getattr(Config(), sec))}
            assert set(values) <= known, (name, sec)


# ---------------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text,needle",
    [
        ("[matching]\npairing_distance = -0.5\n", "matching.pairing_distance"),
        ("[matching]\npairing_distance = 0\n", "matching.pairing_distance"),
        ("[matching]\npairing_distance = inf\n", "matching.pairing_distance"),
        ("[matching]\npairing_distance = nan\n", "matching.pairing_distance"),
        ("[segmentation]\ngap_difference = -0.1\n", "segmentation.gap_difference"),
        ('[fuzzy]\npoint_rules = ["MSS", "MSS", "BMM", "BBM", "SMX"]\n', "fuzzy.point_rules"),
        ('[fuzzy]\npoint_rules = ["MSS", "MSS", "BMM", "BBM"]\n', "fuzzy.point_rules"),
        ('[fuzzy]\nline_rules = ["SSM", "SMB", "MBBS"]\n', "fuzzy.line_rules"),
        (
            '[fuzzy]\nvirtual_distance_rules = ["SSM", "SSM", "SMB", "MBB", "bbb"]\n',
            "fuzzy.virtual_distance_rules",
        ),
        (
            "[fuzzy]\ndistance_sets = [[0, 0, 2], [3, 2, 4], [2, 4, 6], [4, 6, 8], [6, 8, 8]]\n",
            "fuzzy.distance_sets",
        ),
        (
            "[fuzzy]\ndistance_sets = [[0, 0, 2], [0, 2, 4], [2, 4, 6], [4, 6, 8]]\n",
            "fuzzy.distance_sets",
        ),
        (
            "[fuzzy]\nuncertainty_sets = [[0, 0, 0.5], [0, 0.5, 1], [0.5, 1, 1], [1, 1, 1.5]]\n",
            "fuzzy.uncertainty_sets",
        ),
        (
            "[fuzzy]\nline_distance_sets = [[0, 0, 0.025], [0, 0.025, 0.05], [0.05, 0.05, 0.05]]\n",
            "fuzzy.line_distance_sets",
        ),
        (
            (
                "[fuzzy]\nline_distance_sets = "
                "[[0, 0, 0.025], [0.025, 0.05, 0.05], [0, 0.025, 0.05]]\n"
            ),
            "fuzzy.line_distance_sets",
        ),
        (
            "[fuzzy]\ndetection_angle_sets_deg = [[0, 0, 45], [0, 45, 90]]\n",
            "fuzzy.detection_angle_sets",
        ),
        ("[fuzzy]\noutput_centres = [0, 1]\n", "fuzzy.output_centres"),
        ('[fuzzy]\ninference = "sugeno"\n', "fuzzy.inference"),
        ("[fuzzy]\nmamdani_resolution = 5\n", "fuzzy.mamdani_resolution"),
        (
            "[filtering]\ndetection_angle_threshold_deg = 90\n",
            "filtering.detection_angle_threshold",
        ),
        (
            "[filtering]\ndetection_angle_threshold_deg = -1\n",
            "filtering.detection_angle_threshold",
        ),
        (
            "[angular_points]\ninterior_angle_threshold_deg = 180\n",
            "angular_points.interior_angle_threshold",
        ),
        ("[angular_points]\nneighbour_step = 0\n", "angular_points.neighbour_step"),
        (
            "[virtual_points]\nmin_intersection_angle_deg = 0\n",
            "virtual_points.min_intersection_angle",
        ),
        ("[matching]\nmin_pairs = 1\n", "matching.min_pairs"),
        ('[fusion]\nmethod = "median"\n', "fusion.method"),
        ("[fusion]\nmax_solutions = 0\n", "fusion.max_solutions"),
        (
            (
                "[matching]\nuse_break_points = false\nuse_angular_points = false\n"
                "use_virtual_points = false\n"
            ),
            "matching",
        ),
    ],
)
def test_invalid_values_are_config_errors(text: str, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle.replace(".", r"\.")):
        load(text)


def test_invalid_values_in_code_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="pairing_distance"):
        Config(matching=MatchingConfig(pairing_distance=-1.0))
    with pytest.raises(ConfigError, match="point_rules"):
        Config(fuzzy=FuzzyConfig(point_rules=("MSS", "MSS", "BMM", "BBM", "SMX")))
    with pytest.raises(ConfigError, match="detection_angle_threshold"):
        Config(filtering=FilterConfig(detection_angle_threshold=math.radians(95)))
    with pytest.raises(ConfigError, match="pairing_distance"):
        replace(Config(), matching=MatchingConfig(pairing_distance=-1.0))
    with pytest.raises(ConfigError, match="pairing_distance"):
        Config().with_overrides({"matching": {"pairing_distance": -1.0}})


def test_validation_accepts_edge_values() -> None:
    # a shoulder (left == peak) and an integer-valued float are fine; only left > peak is not
    load("[fuzzy]\ndistance_sets = [[0, 0, 3], [0, 3, 4], [3, 4, 6], [4, 6, 10], [6, 10, 10]]\n")
    load("[filtering]\ndetection_angle_threshold_deg = 0\n")
    load("[segmentation]\ngap_difference = 0\n")


def test_configs_are_frozen() -> None:
    cfg = Config()
    with pytest.raises(AttributeError):
        cfg.matching.pairing_distance = 2.0  # type: ignore[misc]


# ---------------------------------------------------------------------------------------------
# Reasons
# ---------------------------------------------------------------------------------------------
def test_every_field_has_a_reason() -> None:
    reasons = Config.reasons()
    expected = {f"{sec}.{f.name}" for sec in SECTIONS for f in fields(getattr(Config(), sec))}
    assert set(reasons) == expected
    empty = sorted(k for k, v in reasons.items() if not (isinstance(v, str) and v.strip()))
    assert empty == []
    # spot checks: the reasons say where the values come from
    assert "22.5" in reasons["filtering.detection_angle_threshold"]
    assert "Table 1" in reasons["fuzzy.point_rules"]


# ---------------------------------------------------------------------------------------------
# Validation generated from the declarations: every numeric field finite and within its bounds
# ---------------------------------------------------------------------------------------------
def _is_numeric(default: object) -> bool:
    if isinstance(default, tuple):
        return bool(default) and all(_is_numeric(x) for x in default)
    return isinstance(default, (int, float)) and not isinstance(default, bool)


NUMERIC = [
    (sec, f.name)
    for sec in SECTIONS
    for f in fields(getattr(Config(), sec))
    if _is_numeric(getattr(getattr(Config(), sec), f.name))
]
SCHEMA = Config.schema()
BOUNDS = [
    (sec, name, kind, getattr(SCHEMA[f"{sec}.{name}"], kind))
    for sec, name in NUMERIC
    for kind in ("ge", "gt", "le", "lt")
    if getattr(SCHEMA[f"{sec}.{name}"], kind) is not None
]


def _default(sec: str, name: str) -> object:
    return getattr(getattr(Config(), sec), name)


def _with_first(value: object, x: object) -> object:
    """``value`` with its first number (of a list, of a list of triangles) replaced by ``x``."""
    if isinstance(value, tuple):
        return (_with_first(value[0], x), *value[1:])
    return x


def _toml_key(sec: str, name: str) -> str:
    return name + "_deg" if SCHEMA[f"{sec}.{name}"].unit == "rad" else name


def _as_toml(value: object) -> object:
    """A code value as a TOML value (tuples as lists; not converted to degrees)."""
    return [_as_toml(v) for v in value] if isinstance(value, tuple) else value


def test_the_numeric_fields_are_all_there() -> None:
    # the parametrised tests below run over these: make sure they are not vacuous
    assert len(NUMERIC) >= 80
    for key in (
        "fuzzy.output_centres",
        "fuzzy.distance_sets",
        "refinement.both_distance",
        "refinement.degenerate_ratio",
        "search.max_points",
        "matching.line_consensus_angle",
    ):
        assert tuple(key.split(".")) in NUMERIC, key
    assert len(BOUNDS) >= len(NUMERIC)


@pytest.mark.parametrize("sec,name", NUMERIC)
def test_every_numeric_field_declares_a_unit_and_a_bound(sec: str, name: str) -> None:
    spec = SCHEMA[f"{sec}.{name}"]
    assert spec.unit in {"", "m", "rad", "s", "1/m", "m/s", "rad/s", "m/√m", "m/rad"}
    assert spec.has_bounds, f"{sec}.{name} declares no bound"
    assert spec.describe()  # something for `fuzzypos config --reasons` to print


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("sec,name", NUMERIC)
def test_non_finite_values_are_rejected_naming_the_key(sec: str, name: str, bad: float) -> None:
    key = rf"{sec}\.{name}"
    value = _with_first(_default(sec, name), bad)
    with pytest.raises(ConfigError, match=key):
        Config().with_overrides({sec: {name: value}})
    # from a file the message names the file too (a TOML integer cannot be nan: floats only)
    if not isinstance(_default(sec, name), int):
        data = {sec: {_toml_key(sec, name): _as_toml(value)}}
        with pytest.raises(ConfigError, match=rf"my\.toml: {key}"):
            Config.from_dict(data, source="my.toml")


def _just_outside(kind: str, bound: float, integer: bool) -> float:
    if kind == "ge":
        return bound - 1 if integer else math.nextafter(bound, -math.inf)
    if kind == "le":
        return bound + 1 if integer else math.nextafter(bound, math.inf)
    return bound  # gt, lt: the bound itself is outside


@pytest.mark.parametrize(
    "sec,name,kind,bound", BOUNDS, ids=[f"{s}.{n}-{k}" for s, n, k, _ in BOUNDS]
)
def test_a_value_beyond_each_bound_is_rejected(
    sec: str, name: str, kind: str, bound: float
) -> None:
    default = _default(sec, name)
    integer = isinstance(default, int) and not isinstance(default, bool)
    bad = _just_outside(kind, bound, integer)
    with pytest.raises(ConfigError, match=rf"{sec}\.{name}"):
        Config().with_overrides({sec: {name: _with_first(default, bad)}})
    if kind in ("ge", "le"):  # an inclusive bound itself is fine
        Config().with_overrides(
            {sec: {name: _with_first(default, int(bound) if integer else bound)}}
        )


def test_the_defaults_lie_within_their_bounds() -> None:
    for key, spec in SCHEMA.items():
        sec, name = key.split(".")
        value: Any = _default(sec, name)
        if _is_numeric(value):
            flat = np.ravel(np.asarray(value, dtype=float))
            assert all(spec.within(float(v)) for v in flat), key


def test_fields_that_were_not_validated_are_now() -> None:
    with pytest.raises(ConfigError, match=r"refinement\.both_distance"):
        RefinementConfig(both_distance=float("nan"))
    with pytest.raises(ConfigError, match=r"refinement\.degenerate_ratio"):
        RefinementConfig(degenerate_ratio=-3)
    with pytest.raises(ConfigError, match=r"refinement\.degenerate_ratio"):
        Config().with_overrides({"refinement": {"degenerate_ratio": 1.5}})
    with pytest.raises(ConfigError, match=r"virtual_points\.max_uncertainty"):
        load("[virtual_points]\nmax_uncertainty = 2.0\n")
    with pytest.raises(ConfigError, match=r"search\.after_gap"):
        load("[search]\nafter_gap = -1.0\n")
    with pytest.raises(ConfigError, match=r"refinement\.both_angle"):
        load("[refinement]\nboth_angle_deg = nan\n")


@pytest.mark.parametrize(
    "text,key",
    [
        ("[fuzzy]\noutput_centres = [nan, 0.5, 1.0]\n", r"fuzzy\.output_centres\[0\]"),
        ("[fuzzy]\noutput_centres = [0.0, 0.5, inf]\n", r"fuzzy\.output_centres\[2\]"),
        (
            "[fuzzy]\ndistance_sets = [[0, 0, 2], [0, 2, 4], [2, 4, inf], [4, 6, 8], [6, 8, 8]]\n",
            r"fuzzy\.distance_sets\[2\]\[2\]",
        ),
        (
            "[fuzzy]\ndetection_angle_sets_deg = [[0, 0, 45], [0, nan, 90], [45, 90, 90]]\n",
            r"fuzzy\.detection_angle_sets\[1\]\[1\]",
        ),
        ("[fuzzy]\nuncertainty_sets = [[0, 0, 0.5], [0, 0.5, 1], [0.5, 1, -inf]]\n", "uncertainty"),
    ],
)
def test_non_finite_numbers_inside_lists_are_rejected(text: str, key: str) -> None:
    with pytest.raises(ConfigError, match=key):
        load(text)


def test_validation_errors_from_a_file_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[refinement]\ndegenerate_ratio = -3.0\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        Config.from_toml(path)
    assert str(path) in str(info.value) and "refinement.degenerate_ratio" in str(info.value)


def test_integers_are_required_for_counts_in_code() -> None:
    with pytest.raises(ConfigError, match=r"search\.max_points"):
        Config().with_overrides({"search": {"max_points": 60.5}})
    with pytest.raises(ConfigError, match=r"refinement\.iterations"):
        Config().with_overrides({"refinement": {"iterations": True}})


def test_angle_bounds_are_stated_in_degrees() -> None:
    with pytest.raises(ConfigError, match=r"\[0°, 90°\)"):
        load("[filtering]\ndetection_angle_threshold_deg = 90\n")
    assert SCHEMA["filtering.detection_angle_threshold"].describe().endswith("in [0°, 90°)")
    assert SCHEMA["matching.pairing_distance"].describe() == "m, > 0"
    assert SCHEMA["fusion.method"].choices == ("weighted_mean", "least_squares")


def test_angle_handling_comes_from_the_unit() -> None:
    data = tomllib.loads(Config().to_toml())
    for key, spec in SCHEMA.items():
        sec, name = key.split(".")
        if spec.unit == "rad":
            assert name + "_deg" in data[sec] and name not in data[sec], key
        else:
            assert name in data[sec] and name + "_deg" not in data[sec], key
    assert {k for k, s in SCHEMA.items() if s.unit == "rad"} == {
        f"{s}.{n}" for s, n in ANGLES_DEG
    } | {"fuzzy.detection_angle_sets"}


def test_reasons_and_schema_agree() -> None:
    reasons = Config.reasons()
    assert list(reasons) == list(SCHEMA)
    assert all(reasons[k] == SCHEMA[k].reason for k in SCHEMA)


def test_reasons_say_why_not_what_a_benchmark_printed() -> None:
    # no log names, no "x against y with z" figures: the mechanism, the trade-off, the data
    quoted = re.compile(r"\b(benchmark|intel|aces|demo)\b|against \d|first \d|scan \d|%\)")
    for key, why in Config.reasons().items():
        assert not quoted.search(why), (key, why)


# ---------------------------------------------------------------------------------------------
# The new and moved fields
# ---------------------------------------------------------------------------------------------
def test_the_search_section_and_the_new_fields() -> None:
    cfg = Config()
    assert cfg.search == SearchConfig(
        jump_distance=1.0,
        angle=math.pi,
        angle_step=math.radians(2.0),
        translation_step=0.2,
        distance_penalty=0.1,
        min_inlier_fraction=0.2,
        gate=0.25,
        failure_angle=math.radians(30.0),
        failure_distance=0.4,
        after_gap=1.0,
        max_points=60,
        weak_prior_scale=100.0,
        batch_size=200_000,
    )
    r, m = cfg.refinement, cfg.matching
    assert (r.weight_floor, r.both_min_gain, r.trim_floor, r.gate_steps) == (0.05, 0.02, 0.002, 3)
    assert (r.converged_translation, r.converged_rotation) == (1e-4, 1e-5)
    assert m.line_consensus_angle == math.asin(0.342)
    assert math.sin(m.line_consensus_angle) == 0.342
    assert "20°" in Config.reasons()["matching.line_consensus_angle"]
    assert (m.line_repair_fraction, m.line_passes) == (0.1, 2)
    assert {f.name for f in fields(OdometryConfig)} == {
        "max_speed",
        "max_turn_rate",
        "max_jump_distance",
        "max_jump_angle",
        "trust_stand_still",
    }
    for gone in ("repair_iterations", "repair_distance"):
        assert not hasattr(m, gone)
    assert not hasattr(r, "skip_with_line_pairs")
    assert "repair_iterations" not in PRESETS["paper"]["matching"]


def test_new_angles_round_trip_exactly() -> None:
    cfg = Config()
    data = tomllib.loads(cfg.to_toml())
    assert math.radians(data["refinement"]["converged_rotation_deg"]) == 1e-5
    assert math.radians(data["matching"]["line_consensus_angle_deg"]) == math.asin(0.342)
    assert data["search"]["angle_deg"] == 180.0


@settings(max_examples=60)
@given(
    deg=st.floats(0.0, 89.0, allow_nan=False),
    dist=st.floats(1e-3, 100.0, allow_nan=False),
    frac=st.floats(0.0, 1.0),
    count=st.integers(1, 10**6),
)
def test_round_trip_of_arbitrary_values(deg: float, dist: float, frac: float, count: int) -> None:
    cfg = Config().with_overrides(
        {
            "filtering": {"detection_angle_threshold": math.radians(deg)},
            "matching": {"line_consensus_angle": math.radians(deg + 1.0), "pairing_distance": dist},
            "refinement": {"degenerate_ratio": frac, "converged_rotation": math.radians(dist)},
            "search": {"max_points": count, "gate": dist},
        }
    )
    assert Config.from_dict(tomllib.loads(cfg.to_toml())) == cfg


# ---------------------------------------------------------------------------------------------
# Files written by older versions
# ---------------------------------------------------------------------------------------------
# the sections of `fuzzypos config` (before issue 9) that changed since, verbatim
OLD_CHANGED_SECTIONS = """
[matching]
pairing_distance = 0.5
same_kind_only = true
mutual = true
min_pair_separation = 0.3
min_pairs = 2
use_break_points = false
use_angular_points = true
use_virtual_points = true
repair_iterations = 0
repair_distance = 0.15
match_lines = true
lines_first = true
keyframe_distance = 1.0
keyframe_angle_deg = 30.0
line_min_pairs = 2
line_angle_gate_deg = 3.0
line_angle_gate_prior_deg = 8.0
line_distance_gate = 0.2
line_distance_gate_prior = 0.5
line_overlap_margin = 0.5
line_prior_sigma = 0.05
line_trim_angle_deg = 0.2
line_inlier_distance = 0.05

[refinement]
enabled = true
max_distance = 0.3
min_distance = 0.1
iterations = 15
residual_scale = 0.05
point_sigma = 0.05
degenerate_ratio = 0.1
local_map_keyframes = 2
length_weight_max = 5.0
length_cap = 3.0
hold_tolerance = 0.03
neighbour_distance = 0.3
neighbour_ratio = 0.05
neighbour_step = 2
min_points = 20
min_inlier_fraction = 0.4
skip_with_line_pairs = 0
also_from_odometry = true
both_distance = 0.05
both_angle_deg = 1.0
prior_from_features = true
max_bend_angle_deg = 30.0
prior_sigma = 0.05
prior_sigma_angle_deg = 2.0
max_correction = 0.5

[odometry]
max_speed = 1.5
max_turn_rate = 2.0
max_jump_distance = 0.25
max_jump_angle_deg = 20.0
jump_search_distance = 1.0
search_angle_deg = 180.0
search_angle_step_deg = 2.0
search_translation_step = 0.2
search_distance_penalty = 0.1
search_min_inlier_fraction = 0.2
search_gate = 0.25
failure_search_angle_deg = 30.0
failure_search_distance = 0.4
search_after_gap = 1.0
trust_stand_still = true
"""
OLD_MOVED = {
    "odometry.jump_search_distance": "search.jump_distance",
    "odometry.search_angle_deg": "search.angle_deg",
    "odometry.search_angle_step_deg": "search.angle_step_deg",
    "odometry.search_translation_step": "search.translation_step",
    "odometry.search_distance_penalty": "search.distance_penalty",
    "odometry.search_min_inlier_fraction": "search.min_inlier_fraction",
    "odometry.search_gate": "search.gate",
    "odometry.failure_search_angle_deg": "search.failure_angle_deg",
    "odometry.failure_search_distance": "search.failure_distance",
    "odometry.search_after_gap": "search.after_gap",
}
OLD_REMOVED = [
    "matching.repair_iterations",
    "matching.repair_distance",
    "refinement.skip_with_line_pairs",
]


def old_config_text() -> str:
    """What `fuzzypos config` printed before issue 9: the unchanged sections as written today."""
    data = Config().to_dict()
    unchanged = {
        k: v for k, v in data.items() if k not in ("matching", "refinement", "odometry", "search")
    }
    head = tomli_w.dumps(
        {
            k: unchanged[k]
            for k in (
                "fuzzy",
                "filtering",
                "segmentation",
                "angular_points",
                "lines",
                "virtual_points",
            )
        }
    )
    fusion = tomli_w.dumps({"fusion": unchanged["fusion"]})
    matching, rest = OLD_CHANGED_SECTIONS.split("[refinement]")
    return head + matching + fusion + "\n[refinement]" + rest


def _messages(caught: list[warnings.WarningMessage]) -> list[str]:
    assert all(issubclass(w.category, FutureWarning) for w in caught)
    return [str(w.message) for w in caught]


def test_an_old_config_file_loads_with_warnings(tmp_path: Path) -> None:
    path = tmp_path / "old.toml"
    path.write_text(old_config_text(), encoding="utf-8")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cfg = Config.from_toml(path)
    assert cfg == Config()
    messages = _messages(caught)
    assert len(messages) == len(OLD_MOVED) + len(OLD_REMOVED)
    for old, new in OLD_MOVED.items():
        assert any(f"{old} has moved to {new}" in m and str(path) in m for m in messages), old
    for old in OLD_REMOVED:
        assert any(f"{old} was removed" in m for m in messages), old


def test_a_moved_key_is_read_in_its_new_place() -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cfg = load("[odometry]\nsearch_angle_deg = 90\nsearch_gate = 0.3\n")
    assert _messages(caught) == [
        (
            "config: odometry.search_angle_deg has moved to search.angle_deg; it is read there, "
            "please rename it"
        ),
        "config: odometry.search_gate has moved to search.gate; it is read there, please rename it",
    ]
    assert cfg.search.angle == math.radians(90.0)
    assert cfg.search.gate == 0.3
    assert cfg.odometry == Config().odometry
    # the new place's bounds apply, naming the new key
    with pytest.warns(FutureWarning), pytest.raises(ConfigError, match=r"search\.gate"):
        load("[odometry]\nsearch_gate = -1.0\n")


def test_a_moved_key_given_in_both_places_is_an_error() -> None:
    with pytest.raises(ConfigError, match=r"odometry\.search_gate .*search\.gate"):
        load("[odometry]\nsearch_gate = 0.3\n[search]\ngate = 0.3\n")


@pytest.mark.parametrize(
    "text",
    [
        "[matching]\nrepair_iterations = 0\n",
        "[matching]\nrepair_distance = 0.4\n",
        "[refinement]\nskip_with_line_pairs = 0\n",
    ],
)
def test_a_removed_key_with_its_no_op_value_is_ignored(text: str) -> None:
    with pytest.warns(FutureWarning, match="was removed"):
        assert load(text) == Config()


@pytest.mark.parametrize(
    "text,key",
    [
        ("[matching]\nrepair_iterations = 2\n", "matching.repair_iterations"),
        ("[matching]\nrepair_iterations = false\n", "matching.repair_iterations"),
        ("[refinement]\nskip_with_line_pairs = 3\n", "refinement.skip_with_line_pairs"),
    ],
)
def test_a_removed_key_that_would_do_something_is_an_error(text: str, key: str) -> None:
    with pytest.raises(ConfigError, match=rf"{key.replace('.', chr(92) + '.')}.*removed"):
        load(text)


def test_with_overrides_knows_only_the_new_names() -> None:
    with pytest.raises(ConfigError, match="search_gate"):
        Config().with_overrides({"odometry": {"search_gate": 0.3}})


def test_preset_line_in_from_dict() -> None:
    assert Config.from_dict({"preset": "paper"}) == Config.preset("paper")
    with pytest.raises(ConfigError, match="papr"):
        Config.from_dict({"preset": "papr"})
    assert Config.from_dict({"preset": "paper"}, base=Config.preset("paper")) == Config.preset(
        "paper"
    )
    with pytest.raises(ConfigError, match="preset"):
        Config.from_dict({"preset": "paper"}, base=Config())


# ---------------------------------------------------------------------------------------------
# The command line loads files the same way
# ---------------------------------------------------------------------------------------------
def _cli(*args: str) -> Result:
    from fuzzypos.cli import app

    return CliRunner().invoke(app, list(args))


def test_cli_loads_an_old_config_file(tmp_path: Path) -> None:
    path = tmp_path / "old.toml"
    path.write_text(old_config_text(), encoding="utf-8")
    res = _cli("config", "--config", str(path))
    assert res.exit_code == 0, res.output
    assert Config.from_dict(tomllib.loads(res.stdout)) == Config()
    assert "fuzzypos: warning:" in res.stderr
    assert "odometry.search_angle_deg has moved to search.angle_deg" in res.stderr
    assert "matching.repair_iterations was removed" in res.stderr


def test_cli_honours_the_files_preset_line(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text('preset = "paper"\n[matching]\npairing_distance = 0.7\n', encoding="utf-8")
    res = _cli("config", "--config", str(path))
    assert res.exit_code == 0, res.output
    got = Config.from_dict(tomllib.loads(res.stdout))
    assert got == Config.preset("paper").with_overrides({"matching": {"pairing_distance": 0.7}})
    # --preset naming the same configuration agrees; another one is an error
    assert _cli("config", "--preset", "paper", "--config", str(path)).exit_code == 0
    path.write_text('preset = "papr"\n', encoding="utf-8")
    res = _cli("config", "--config", str(path))
    assert res.exit_code == 2 and "papr" in res.output


def test_cli_rejects_a_removed_setting(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text("[matching]\nrepair_iterations = 2\n", encoding="utf-8")
    res = _cli("config", "--config", str(path))
    assert res.exit_code == 2 and "repair_iterations" in res.output and "removed" in res.output


def test_cli_reasons_print_unit_and_bounds() -> None:
    res = _cli("config", "--reasons")
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    assert len(lines) == len(SCHEMA)
    assert any(line.startswith("matching.pairing_distance [m, > 0]: ") for line in lines)
    assert any(line.startswith("search.max_points [>= 1]: ") for line in lines)


def test_same_as_last_call_by_identity_only():
    from fuzzypos.config import same_as_last_call

    calls = []

    @same_as_last_call
    def derived(section, scale):
        calls.append(section)
        return (section.min_distance * scale,)

    a = Config().refinement
    first = derived(a, 2.0)
    assert derived(a, 2.0) is first and len(calls) == 1  # the very same objects: remembered
    b = replace(a, min_distance=0.2)
    assert derived(b, 2.0) == (0.4,) and len(calls) == 2  # another section: computed
    assert derived(a, 3.0) == (a.min_distance * 3.0,) and len(calls) == 3
    assert derived(a, scale=3.0) == (a.min_distance * 3.0,)  # keywords: always computed
