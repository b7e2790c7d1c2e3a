"""The configuration of the whole pipeline: :class:`Config` (:mod:`.core`), its sections
(:mod:`.features`, :mod:`.pipeline`, :mod:`.uncertainty`, :mod:`.scanner`, :mod:`.graph`,
:mod:`.localization`), the
declarations and TOML handling they are built from (:mod:`.schema`) and the settings' reference
(:mod:`.docs`)."""

from __future__ import annotations

from .core import (
    PRESETS,
    AngularPointConfig,
    Config,
    ConfigError,
    CovarianceConfig,
    FieldSpec,
    FilterConfig,
    FusionConfig,
    FuzzyConfig,
    GateConfig,
    LineConfig,
    LocalizationConfig,
    LoopClosureConfig,
    MatchingConfig,
    OdometryConfig,
    OdometryNoiseConfig,
    RefinementConfig,
    ScannerConfig,
    SearchConfig,
    SegmentationConfig,
    VirtualPointConfig,
    same_as_last_call,
)

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
