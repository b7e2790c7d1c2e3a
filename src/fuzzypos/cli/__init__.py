"""The ``fuzzypos`` command line (typer): the commands (:mod:`.commands`), their help and
progress (:mod:`.help`) and their tables (:mod:`.tables`). ``fuzzypos.cli:app`` is the console
script; :func:`main` runs it."""

from __future__ import annotations

from .commands import app, main

__all__ = ["app", "main"]
