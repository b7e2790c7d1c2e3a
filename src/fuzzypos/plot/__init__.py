"""The figures (matplotlib, written as PNG without pyplot): a run's paths, map and errors, and
the feature stages of one scan (:mod:`.figures`)."""

from __future__ import annotations

from .figures import (
    FEATURE_FIGURES,
    plot_errors_vs_distance,
    plot_feature_figures,
    plot_map,
    plot_paths,
)

__all__ = [
    "FEATURE_FIGURES",
    "plot_errors_vs_distance",
    "plot_feature_figures",
    "plot_map",
    "plot_paths",
]
