"""Tests of the configuration: TOML round trip, degrees at the edge, errors that name the key."""

from __future__ import annotations

import math
import sys
from dataclasses import fields, replace
from pathlib import Path

import pytest

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
    ("odometry", "search_angle"): 180.0,
    ("odometry", "search_angle_step"): 2.0,
    ("odometry", "failure_search_angle"): 30.0,
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
            keys.add(f.name + "_deg" if (sec, f.name) in ANGLES_DEG or f.name == "detection_angle_sets" else f.name)
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
    assert cfg.fuzzy.detection_angle_sets[-1] == pytest.approx((math.pi / 4, math.pi / 2, math.pi / 2))


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
        ('[matching]\npairing_distance = "0.5"\n', "matching.pairing_distance"),  # string for a float
        ("[lines]\nmin_points = 4.0\n", "lines.min_points"),  # float for an int
        ("[matching]\npairing_distance = true\n", "matching.pairing_distance"),  # bool for a float
        ("[lines]\nmin_points = true\n", "lines.min_points"),  # bool for an int
        ("[matching]\nmutual = 1\n", "matching.mutual"),  # int for a bool
        ("[fusion]\nmethod = 3\n", "fusion.method"),  # int for a string
        ('[filtering]\ndetection_angle_threshold_deg = "22.5"\n', "filtering.detection_angle_threshold_deg"),
        ("[fuzzy]\npoint_rules = \"MSS\"\n", "fuzzy.point_rules"),  # string for a list
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
    assert Config.from_toml(str(path)) == Config().with_overrides({"matching": {"pairing_distance": 0.7}})


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
        ('[fuzzy]\nvirtual_distance_rules = ["SSM", "SSM", "SMB", "MBB", "bbb"]\n', "fuzzy.virtual_distance_rules"),
        ("[fuzzy]\ndistance_sets = [[0, 0, 2], [3, 2, 4], [2, 4, 6], [4, 6, 8], [6, 8, 8]]\n", "fuzzy.distance_sets"),
        ("[fuzzy]\ndistance_sets = [[0, 0, 2], [0, 2, 4], [2, 4, 6], [4, 6, 8]]\n", "fuzzy.distance_sets"),
        ("[fuzzy]\nuncertainty_sets = [[0, 0, 0.5], [0, 0.5, 1], [0.5, 1, 1], [1, 1, 1.5]]\n", "fuzzy.uncertainty_sets"),
        ("[fuzzy]\nline_distance_sets = [[0, 0, 0.025], [0, 0.025, 0.05], [0.05, 0.05, 0.05]]\n", "fuzzy.line_distance_sets"),
        ("[fuzzy]\nline_distance_sets = [[0, 0, 0.025], [0.025, 0.05, 0.05], [0, 0.025, 0.05]]\n", "fuzzy.line_distance_sets"),
        ("[fuzzy]\ndetection_angle_sets_deg = [[0, 0, 45], [0, 45, 90]]\n", "fuzzy.detection_angle_sets"),
        ("[fuzzy]\noutput_centres = [0, 1]\n", "fuzzy.output_centres"),
        ('[fuzzy]\ninference = "sugeno"\n', "fuzzy.inference"),
        ("[fuzzy]\nmamdani_resolution = 5\n", "fuzzy.mamdani_resolution"),
        ("[filtering]\ndetection_angle_threshold_deg = 90\n", "filtering.detection_angle_threshold"),
        ("[filtering]\ndetection_angle_threshold_deg = -1\n", "filtering.detection_angle_threshold"),
        ("[angular_points]\ninterior_angle_threshold_deg = 180\n", "angular_points.interior_angle_threshold"),
        ("[angular_points]\nneighbour_step = 0\n", "angular_points.neighbour_step"),
        ("[virtual_points]\nmin_intersection_angle_deg = 0\n", "virtual_points.min_intersection_angle"),
        ("[matching]\nmin_pairs = 1\n", "matching.min_pairs"),
        ('[fusion]\nmethod = "median"\n', "fusion.method"),
        ("[fusion]\nmax_solutions = 0\n", "fusion.max_solutions"),
        (
            "[matching]\nuse_break_points = false\nuse_angular_points = false\nuse_virtual_points = false\n",
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
