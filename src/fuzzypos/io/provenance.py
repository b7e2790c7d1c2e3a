"""Provenance and bookkeeping of runs: what ran (:func:`git_hash`) on what
(:func:`file_sha256`), and writing the JSON records (:func:`write_json`, NaN/inf as ``null``
through :func:`json_safe`)."""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from ._common import write_text_file

__all__ = ["file_sha256", "git_hash", "json_safe", "write_json"]


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes; for a directory (a ROS2 bag) of every file under it in
    sorted order of their relative paths (POSIX), each contributing its relative path, a NUL
    byte, its 8-byte big-endian size and its bytes."""
    p = Path(path)
    h = hashlib.sha256()

    def feed(f: Path) -> None:
        with open(f, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)

    if p.is_dir():
        files = sorted(
            (f for f in p.rglob("*") if f.is_file()), key=lambda f: f.relative_to(p).as_posix()
        )
        for f in files:
            h.update(f.relative_to(p).as_posix().encode("utf-8") + b"\x00")
            h.update(f.stat().st_size.to_bytes(8, "big"))
            feed(f)
    else:
        feed(p)
    return h.hexdigest()


def git_hash() -> str | None:
    """The commit of the source tree fuzzypos runs from (``git rev-parse HEAD`` in the
    package's directory), when that directory is part of a git work tree whose
    ``src/fuzzypos`` it is; None otherwise (installed package, no git, any failure)."""
    here = Path(__file__).resolve().parents[1]  # src/fuzzypos (this module is in io/)
    try:

        def git(*args: str) -> str:
            return subprocess.run(
                ["git", "-C", str(here), *args],
                capture_output=True,
                text=True,
                timeout=5,
                check=True,
            ).stdout.strip()

        top = Path(git("rev-parse", "--show-toplevel")).resolve()
        if (top / "src" / "fuzzypos").resolve() != here:
            return None
        commit = git("rev-parse", "HEAD")
        return commit or None
    except Exception:  # never fail a run for its provenance
        return None


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def json_safe(o: Any) -> Any:
    """NaN/inf → None (JSON has none), recursively through dicts, lists and tuples (tuples
    become lists)."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: json_safe(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [json_safe(v) for v in o]
    return o


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` (through :func:`json_safe`; numpy scalars and arrays and paths as JSON)
    to ``path``, indented, by a temporary file renamed over it (removed on failure; a failure
    to write is an :class:`~fuzzypos.io.OutputWriteError`)."""
    text = json.dumps(json_safe(data), indent=2, default=_json_default, allow_nan=False)
    write_text_file(path, text + "\n")
