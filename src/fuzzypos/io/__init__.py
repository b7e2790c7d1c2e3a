"""Reading and writing robot logs and trajectories.

- :mod:`fuzzypos.io.carmen`: CARMEN logs (``.clf``, plain or gzip), read as a stream and written;
- :mod:`fuzzypos.io.tum`: TUM trajectories (``t x y z qx qy qz qw``, what ``evo`` reads).

Every format error is a :class:`LogFormatError` (a :class:`ValueError`) naming the file, the
line and what is wrong.
"""

from __future__ import annotations

from ._common import GZIP_MAGIC, LogFormatError, LogRecord, open_text
from .carmen import (
    CONVENTIONS,
    CarmenFormatError,
    CarmenReader,
    CarmenRecord,
    carmen_beam_geometry,
    read_carmen,
    write_carmen,
)
from .tum import TumFormatError, read_tum, write_tum

__all__ = [
    "CONVENTIONS",
    "GZIP_MAGIC",
    "CarmenFormatError",
    "CarmenReader",
    "CarmenRecord",
    "LogFormatError",
    "LogRecord",
    "TumFormatError",
    "carmen_beam_geometry",
    "open_text",
    "read_carmen",
    "read_tum",
    "write_carmen",
    "write_tum",
]
