"""One configuration for the whole pipeline: frozen dataclasses, TOML in and out.

Every threshold and every membership function lives here, each declaring why it has its value,
its unit and its bounds (``_field(default, reason, unit=..., ge=..., gt=..., le=..., lt=...)``;
``reasons()``, ``schema()``). Validation is generated from those declarations, plus the few
checks they cannot express (``CHECKS``, below). Angles (unit ``"rad"``) are radians in
the code; in TOML they sit in keys ending in ``_deg`` and are converted once, at load. Unknown
keys are an error that names the key; keys of older files that moved or were removed are
translated with a FutureWarning.

``Config()`` is the default: the best configuration measurement supports (docs/method.md).
``Config.preset("paper")`` keeps every rule and value the paper states (with SPEC's corrections)
and takes our defaults where the paper states none.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import tomli_w

from .features import (
    AngularPointConfig,
    FilterConfig,
    FuzzyConfig,
    LineConfig,
    SegmentationConfig,
    VirtualPointConfig,
)
from .graph import LoopClosureConfig
from .localization import LocalizationConfig
from .pipeline import FusionConfig, MatchingConfig, OdometryConfig, RefinementConfig, SearchConfig
from .scanner import ScannerConfig
from .schema import (
    SECTIONS,
    ConfigError,
    FieldSpec,
    check_rules,
    check_section,
    check_sets,
    convert_section,
    read_toml,
    section_to_dict,
    spec_of,
    translate_legacy,
)
from .uncertainty import CovarianceConfig, GateConfig, OdometryNoiseConfig

__all__ = [
    "ConfigError",
    "Config",
    "FuzzyConfig",
    "FilterConfig",
    "SegmentationConfig",
    "AngularPointConfig",
    "LineConfig",
    "VirtualPointConfig",
    "MatchingConfig",
    "FusionConfig",
    "RefinementConfig",
    "OdometryConfig",
    "SearchConfig",
    "CovarianceConfig",
    "OdometryNoiseConfig",
    "GateConfig",
    "ScannerConfig",
    "LoopClosureConfig",
    "LocalizationConfig",
    "FieldSpec",
    "same_as_last_call",
    "PRESETS",
]

_SECTIONS = SECTIONS  # [section] name -> class, filled by @section


@dataclass(frozen=True)
class Config:
    """Every threshold and membership function of the pipeline."""

    fuzzy: FuzzyConfig = field(default_factory=FuzzyConfig)
    filtering: FilterConfig = field(default_factory=FilterConfig)
    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    angular_points: AngularPointConfig = field(default_factory=AngularPointConfig)
    lines: LineConfig = field(default_factory=LineConfig)
    virtual_points: VirtualPointConfig = field(default_factory=VirtualPointConfig)
    matching: MatchingConfig = field(default_factory=MatchingConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    refinement: RefinementConfig = field(default_factory=RefinementConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    search: SearchConfig = field(default_factory=SearchConfig)
    scanner: ScannerConfig = field(default_factory=ScannerConfig)
    covariance: CovarianceConfig = field(default_factory=CovarianceConfig)
    odometry_noise: OdometryNoiseConfig = field(default_factory=OdometryNoiseConfig)
    gate: GateConfig = field(default_factory=GateConfig)
    loop_closure: LoopClosureConfig = field(default_factory=LoopClosureConfig)
    localization: LocalizationConfig = field(default_factory=LocalizationConfig)

    def __post_init__(self) -> None:
        validate(self, _SECTIONS)

    # -- presets -------------------------------------------------------------------------------
    @classmethod
    def preset(cls, name: str) -> Config:
        """A named configuration: ``default`` or ``paper``."""
        try:
            overrides = PRESETS[name]
        except KeyError:
            known = ", ".join(sorted(PRESETS))
            raise ConfigError(f"unknown preset {name!r}; known: {known}") from None
        return cls().with_overrides(overrides)

    def with_overrides(self, overrides: Mapping[str, Mapping[str, Any]]) -> Config:
        """A copy with ``{section: {field: value}}`` replaced (code units: radians)."""
        sections = {}
        for sec_name, values in overrides.items():
            if sec_name not in _SECTIONS:
                raise ConfigError(f"unknown config section {sec_name!r}")
            sec = getattr(self, sec_name)
            known = {f.name for f in fields(sec)}
            for k in values:
                if k not in known:
                    raise ConfigError(f"unknown config key {sec_name}.{k}")
            sections[sec_name] = replace(sec, **dict(values))
        return replace(self, **sections)

    # -- TOML ----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain TOML-ready dictionary, angles in ``_deg`` keys."""
        return {name: section_to_dict(getattr(self, name)) for name in _SECTIONS}

    @classmethod
    def from_dict(
        cls, data: Mapping[str, Any], base: Config | None = None, source: str = "config"
    ) -> Config:
        """Build from a TOML-shaped mapping; keys missing keep ``base``.

        Without ``base``, a top-level ``preset = "<name>"`` picks it (default: ``Config()``);
        with one, a ``preset`` line must name that same configuration. Keys of older files
        are read in their new place (or dropped) with a FutureWarning, see :mod:`.schema`.
        Every error names ``source`` and the key.
        """
        base = base_for(cls, data, base, source)
        data = translate_legacy(data, source)
        overrides: dict[str, dict[str, Any]] = {}
        for sec_name, values in data.items():
            if sec_name == "preset":
                continue
            if sec_name not in _SECTIONS:
                raise ConfigError(f"{source}: unknown config section [{sec_name}]")
            if not isinstance(values, Mapping):
                raise ConfigError(f"{source}: [{sec_name}] must be a table")
            overrides[sec_name] = convert_section(getattr(base, sec_name), sec_name, values, source)
        try:
            return base.with_overrides(overrides)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from None

    @classmethod
    def from_toml(cls, path: str | Path, base: Config | None = None) -> Config:
        """Load a TOML file; an optional top-level ``preset = "paper"`` picks the base."""
        return cls.from_dict(read_toml(path), base=base, source=str(path))

    def to_toml(self) -> str:
        return tomli_w.dumps(self.to_dict())

    def dump(self, path: str | Path) -> None:
        Path(path).write_text(self.to_toml(), encoding="utf-8")

    @staticmethod
    def reasons() -> dict[str, str]:
        """``{"section.key": reason}`` for every setting."""
        return {key: spec.reason for key, spec in Config.schema().items()}

    @staticmethod
    def schema() -> dict[str, FieldSpec]:
        """``{"section.key": FieldSpec}`` for every setting: reason, unit, bounds, choices."""
        return {
            f"{sec_name}.{f.name}": spec_of(f)
            for sec_name, cls_ in _SECTIONS.items()
            for f in fields(cls_)
        }


# The paper's way: every rule and value it states, with SPEC's corrections; ours elsewhere.
PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "default": {},
    "paper": {
        "angular_points": {"refine": False, "pair_unrefined": True},
        "matching": {
            "same_kind_only": False,
            "mutual": False,
            "use_break_points": True,
            "use_angular_points": True,
            "use_virtual_points": True,
            "match_lines": False,
        },
        "fusion": {"method": "weighted_mean", "robust": False},
        "refinement": {"enabled": False},
    },
}


_P = ParamSpec("_P")
_R = TypeVar("_R")


def same_as_last_call(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """``func`` (a function of frozen config sections and plain values, cached or not) that
    returns its last result again when called with the very same objects: an identity check
    per argument, where an ``lru_cache`` hashes a section's every field on each call."""
    last: tuple[tuple[Any, ...], _R] | None = None

    @functools.wraps(func)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        nonlocal last
        if kwargs:
            return func(*args, **kwargs)
        seen = last
        if seen is not None and len(seen[0]) == len(args):
            for a, b in zip(args, seen[0]):
                if a is not b:
                    break
            else:
                return seen[1]
        out = func(*args, **kwargs)
        last = (args, out)
        return out

    return wrapper


# -- what loading needs of Config itself (here, so that schema never imports Config) ----------
def base_for(
    cls: type[Config], data: Mapping[str, Any], base: Config | None, source: str
) -> Config:
    """The base a mapping loads onto: ``base``, else the one its ``preset`` line names."""
    if "preset" not in data:
        return base if base is not None else cls()
    name = data["preset"]
    if not isinstance(name, str):
        raise ConfigError(f"{source}: preset must be a string, got {name!r}")
    try:
        named = cls.preset(name)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    if base is not None and base != named:
        raise ConfigError(f"{source}: preset = {name!r} differs from the base configuration given")
    return named


# -- the checks the declarations cannot express ----------------------------------------------------
def _check_fuzzy(cfg: Config) -> None:
    fz = cfg.fuzzy
    for name, n in (
        ("detection_angle_sets", 3),
        ("distance_sets", 5),
        ("uncertainty_sets", 3),
        ("line_distance_sets", 3),
        ("virtual_distance_sets", 5),
    ):
        check_sets(name, getattr(fz, name), n)
    if len(fz.output_centres) != 3:
        raise ConfigError("fuzzy.output_centres needs 3 values (S, M, B)")
    check_rules("point_rules", fz.point_rules, 5, 3)
    check_rules("line_rules", fz.line_rules, 3, 3)
    check_rules("virtual_pair_rules", fz.virtual_pair_rules, 3, 3)
    check_rules("virtual_distance_rules", fz.virtual_distance_rules, 5, 3)


def _check_distances(cfg: Config) -> None:
    if cfg.refinement.min_distance > cfg.refinement.max_distance:
        raise ConfigError("refinement.min_distance must not exceed refinement.max_distance")


def _check_feature_kinds(cfg: Config) -> None:
    m = cfg.matching
    if not (m.use_break_points or m.use_angular_points or m.use_virtual_points):
        raise ConfigError("matching: at least one kind of feature point must be used")


def _check_bands(cfg: Config) -> None:
    """``scanner.no_return_bands``: ``[low, high]`` pairs with ``low <= high``."""
    for i, band in enumerate(cfg.scanner.no_return_bands):
        if not isinstance(band, (tuple, list)) or len(band) != 2:
            raise ConfigError(
                f"scanner.no_return_bands[{i}] must be a [low, high] pair, got {band!r}"
            )
        if band[0] > band[1]:
            raise ConfigError(
                f"scanner.no_return_bands[{i}] needs low <= high, got [{band[0]!r}, {band[1]!r}]"
            )


CHECKS: tuple[Callable[[Config], None], ...] = (
    _check_fuzzy,
    _check_distances,
    _check_feature_kinds,
    _check_bands,
)


def validate(cfg: Config, sections: Mapping[str, type]) -> None:
    """Every field against its declaration (finite, within bounds, a choice), then CHECKS."""
    for sec_name in sections:
        check_section(sec_name, getattr(cfg, sec_name))
    for check in CHECKS:
        check(cfg)
