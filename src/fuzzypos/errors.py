"""The root of every exception fuzzypos raises on purpose.

Each of fuzzypos's exception classes derives from :class:`FuzzyposError` and from
:class:`ValueError` (bad input: a malformed log line, a config key out of bounds, a log
fuzzypos cannot read) or :class:`OSError` (files and folders, a missing optional
dependency), so that ``except FuzzyposError`` catches everything fuzzypos reports and
``except ValueError`` / ``except OSError`` keep working. The command line catches them once
and prints one line (exit 2).
"""

from __future__ import annotations

__all__ = ["FuzzyposError"]


class FuzzyposError(Exception):
    """An error fuzzypos reports: its message names the file, the line or key, and what is
    wrong. Every exception class of the package derives from it."""
