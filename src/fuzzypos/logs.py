"""Deprecated path: the log reading moved to :mod:`fuzzypos.io.logs` (``from fuzzypos.io
import open_log``). This module re-exports its names for the scripts that import them here."""

from __future__ import annotations

from .io.logs import (
    LOG_KINDS,
    LogInfo,
    NoReturnCount,
    OpenLog,
    SelectionError,
    StampCheck,
    StampError,
    UnknownLogError,
    describe_log,
    empty_stretch,
    find_no_return_values,
    log_kind,
    open_log,
    parse_laser_offset,
    select_records,
    select_stamps,
    survey_log,
)

__all__ = [
    "LOG_KINDS",
    "LogInfo",
    "NoReturnCount",
    "OpenLog",
    "SelectionError",
    "StampCheck",
    "StampError",
    "UnknownLogError",
    "describe_log",
    "empty_stretch",
    "find_no_return_values",
    "log_kind",
    "open_log",
    "parse_laser_offset",
    "select_records",
    "select_stamps",
    "survey_log",
]
