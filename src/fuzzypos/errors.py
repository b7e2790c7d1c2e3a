"""The root of every exception fuzzypos raises on purpose.

Each of fuzzypos's exception classes derives from :class:`FuzzyposError` and from
:class:`ValueError` (bad input: a malformed log line, a config key out of bounds, a log
fuzzypos cannot read) or :class:`OSError` (files and folders, a missing optional
dependency), so that ``except FuzzyposError`` catches everything fuzzypos reports and
``except ValueError`` / ``except OSError`` keep working. The command line catches them once
and prints one line (exit 2).

A message that names an argument of the library (``max_scans must be at least 1``) is made
of :class:`Words`: the library's text, and the argument as an :class:`Argument` that a caller
with other names for the arguments (the command line's ``--max-scans``) words its own way
(:meth:`FuzzyposError.worded`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["Argument", "ArgumentError", "FuzzyposError", "Words"]


@dataclass(frozen=True)
class Argument:
    """An argument a message names: ``name`` then ``suffix`` in the library's words
    (``scan_topic=``), the caller's name for it then ``then`` in the caller's (``--scan-topic
    ``)."""

    name: str
    suffix: str = ""
    then: str = ""

    @classmethod
    def given(cls, name: str) -> Argument:
        """``name=`` before its value (``scan_topic='/x'``; ``--scan-topic '/x'``)."""
        return cls(name, "=", " ")


class Words(str):
    """A message naming library arguments: the library's text, with :attr:`parts` (text and
    :class:`Argument`) from which :meth:`worded` says it with other names for them."""

    parts: tuple[str | Argument, ...]

    def __new__(cls, *parts: str | Argument) -> Words:
        text = "".join(p if isinstance(p, str) else p.name + p.suffix for p in parts)
        self = super().__new__(cls, text)
        self.parts = tuple(parts)
        return self

    def __reduce__(self) -> tuple[type, tuple[str | Argument, ...]]:
        return (type(self), self.parts)

    def worded(self, names: Mapping[str, str]) -> str:
        """The message with each argument ``names`` has a name for called that name."""
        return "".join(
            p
            if isinstance(p, str)
            else (names[p.name] + p.then if p.name in names else p.name + p.suffix)
            for p in self.parts
        )


def worded(text: str, names: Mapping[str, str]) -> str:
    """``text`` (a :class:`Words` or plain text) with the arguments it names as ``names``
    names them."""
    return text.worded(names) if isinstance(text, Words) else text


class FuzzyposError(Exception):
    """An error fuzzypos reports: its message names the file, the line or key, and what is
    wrong. Every exception class of the package derives from it."""

    def worded(self, names: Mapping[str, str]) -> str:
        """The message, with the library arguments it names (if it is :class:`Words`) called
        as ``names`` calls them (the command line: ``{"max_scans": "--max-scans"}``)."""
        if len(self.args) == 1 and isinstance(self.args[0], Words):
            return self.args[0].worded(names)
        return str(self)


class ArgumentError(FuzzyposError, ValueError):
    """A bad argument to a library function; the message (:class:`Words`) names it."""
