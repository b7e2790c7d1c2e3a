"""The ``fuzzypos`` command line (typer): the commands (:mod:`.main`), their help and progress
(:mod:`.help`) and their tables (:mod:`.tables`). ``fuzzypos.cli:app`` is the console script."""

from __future__ import annotations

from .main import app

__all__ = ["app"]
