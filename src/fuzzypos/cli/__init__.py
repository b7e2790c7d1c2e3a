"""The ``fuzzypos`` command line (typer): the ``app``, its error handling and what the
commands share (:mod:`.app`); the commands, a module per group (:mod:`.run`;
:mod:`.localize`; :mod:`.logs`: ``info``, ``plot-scan``; :mod:`.evaluate`: ``evaluate``,
``benchmark``; :mod:`.batch`; :mod:`.demo`: ``demo``, ``simulate``, ``config``); their help
and progress (:mod:`.help`) and their tables (:mod:`.tables`). A command module registers on
the app with ``from .app import app`` and ``@app.command()``; importing it here registers
it. ``fuzzypos.cli:app`` is the console script; :func:`main` runs it."""

from __future__ import annotations

from . import batch, demo, evaluate, localize, logs, run  # noqa: F401  (each registers)
from .app import app, main

__all__ = ["app", "main"]
