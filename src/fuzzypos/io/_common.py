"""What the log readers and writers share: the typed format errors, opening plain or gzip
text by content, and atomic writes."""

from __future__ import annotations

import contextlib
import gzip
import io
import math
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, NamedTuple, Union

import numpy as np
from numpy.typing import NDArray

from ..geometry import Pose2D
from ..scan import LaserScan

__all__ = ["GZIP_MAGIC", "LogFormatError", "LogRecord", "open_text"]

PathLike = Union[str, "os.PathLike[str]"]
FloatArray = NDArray[np.float64]

GZIP_MAGIC = b"\x1f\x8b"


class LogRecord(NamedTuple):
    """One scan of a log with the robot's raw odometry pose at it (None where the log has no
    odometry) and, for a simulated log, the true pose (else None). The scan's
    ``sensor_pose`` is the laser's mounting pose on the robot."""

    scan: LaserScan
    odometry: Pose2D | None
    truth: Pose2D | None = None


# -- errors --------------------------------------------------------------------------------
class LogFormatError(ValueError):
    """A malformed line in a log file: ``"<file>:<line>: <what>"``.

    ``path`` is the file as given, ``line`` the 1-based line number (0 when the problem is
    not on one line) and ``reason`` what is wrong.
    """

    def __init__(self, path: PathLike, line: int, reason: str) -> None:
        self.path = os.fspath(path)
        self.line = int(line)
        self.reason = reason
        where = f"{self.path}:{self.line}" if self.line > 0 else self.path
        super().__init__(f"{where}: {reason}")

    def __reduce__(self) -> tuple[type, tuple[str, int, str]]:  # picklable across processes
        return (type(self), (self.path, self.line, self.reason))


def numeric_rows(
    path: PathLike, names: tuple[str, ...], error: type[LogFormatError]
) -> Iterator[tuple[int, list[float]]]:
    """``(line number, values)`` for every line of a text file (plain or gzip) holding exactly
    ``len(names)`` finite numbers; ``#`` comments and blank lines are skipped. Anything else
    raises ``error`` naming the file, the line and the field (by ``names``)."""
    with open_text(path) as fh:
        for lineno, line in enumerate(fh, start=1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            tok = s.split()
            if len(tok) != len(names):
                fields = " ".join(names)
                raise error(
                    path, lineno, f"expected {len(names)} fields ({fields}), got {len(tok)}"
                )
            vals = []
            for what, f in zip(names, tok):
                try:
                    v = float(f)
                except ValueError:
                    raise error(path, lineno, f"{what} is not a number: {f!r}") from None
                if not math.isfinite(v):
                    raise error(path, lineno, f"{what} must be finite, got {f!r}")
                vals.append(v)
            yield lineno, vals


# -- files ---------------------------------------------------------------------------------
def open_text(path: PathLike) -> IO[str]:
    """Open a text log for reading, decompressing gzip when the file starts with its magic
    bytes (whatever its name). Undecodable bytes become U+FFFD (and fail to parse as numbers
    rather than aborting the read)."""
    with open(path, "rb") as f:
        magic = f.read(2)
    # the caller closes the returned stream, which closes these
    raw: gzip.GzipFile | io.BufferedReader = (
        gzip.open(path, "rb") if magic == GZIP_MAGIC else open(path, "rb")  # noqa: SIM115
    )
    return io.TextIOWrapper(raw, encoding="utf-8", errors="replace")


def _write_atomically(path: PathLike, write: Callable[[IO[str]], None]) -> None:
    """Call ``write`` on a text stream that ends up in ``path`` only if it returns: a
    temporary file next to ``path`` is renamed over it, or removed on error. A name ending in
    ``.gz`` gets a gzip file."""
    target = Path(path)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        if target.name.endswith(".gz"):
            with (
                open(tmp, "wb") as raw,
                gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz,
                io.TextIOWrapper(gz, encoding="utf-8", newline="\n") as fh,
            ):
                write(fh)
        else:
            with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
                write(fh)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
