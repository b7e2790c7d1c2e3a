"""One configuration for the whole pipeline: frozen dataclasses, TOML in and out.

Every threshold and every membership function lives here, each declaring why it has its value,
its unit and its bounds (``_field(default, reason, unit=..., ge=..., gt=..., le=..., lt=...)``;
``reasons()``, ``schema()``). Validation is generated from those declarations, plus the few
checks they cannot express (``_config_schema.CHECKS``). Angles (unit ``"rad"``) are radians in
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

from ._config_features import (
    AngularPointConfig,
    FilterConfig,
    FuzzyConfig,
    LineConfig,
    SegmentationConfig,
    VirtualPointConfig,
)
from ._config_graph import LoopClosureConfig
from ._config_pipeline import (
    FusionConfig,
    MatchingConfig,
    OdometryConfig,
    RefinementConfig,
    SearchConfig,
)
from ._config_scanner import ScannerConfig
from ._config_schema import (
    SECTIONS,
    ConfigError,
    FieldSpec,
    base_for,
    convert_section,
    read_toml,
    section_to_dict,
    spec_of,
    translate_legacy,
    validate,
)
from ._config_uncertainty import CovarianceConfig, GateConfig, OdometryNoiseConfig

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
        are read in their new place (or dropped) with a FutureWarning, see ``_config_schema``.
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
    per argument, where an ``lru_cache`` hashes a section's every field on each call (about a
    microsecond a section, several per scan)."""
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
