"""What the log readers and writers share: the typed format errors, opening plain or gzip
text by content (from a pipe too), spooling a pipe that must be read more than once, and
writing an output where its path points (:func:`output_target`): a regular file atomically,
a pipe or a character device streamed to."""

from __future__ import annotations

import contextlib
import errno
import gzip
import io
import math
import os
import shutil
import stat
import tempfile
import weakref
import zlib
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import IO, Any, NamedTuple, Union, cast

import numpy as np
from numpy.typing import NDArray

from ..errors import FuzzyposError, worded
from ..geometry import Pose2D
from ..scan import LaserScan

__all__ = [
    "GZIP_MAGIC",
    "GZIP_ERRORS",
    "LogFormatError",
    "LogRecord",
    "OutputPathError",
    "OutputWriteError",
    "Spool",
    "check_output_file",
    "display_name",
    "is_stream",
    "open_text",
    "output_target",
    "spool_if_stream",
    "write_text_file",
]

PathLike = Union[str, "os.PathLike[str]"]
FloatArray = NDArray[np.float64]

GZIP_MAGIC = b"\x1f\x8b"

#: what reading a damaged gzip stream raises (a stream cut short: EOFError; bad data:
#: zlib.error; a bad header, CRC or length: gzip.BadGzipFile, an OSError)
GZIP_ERRORS: tuple[type[BaseException], ...] = (EOFError, zlib.error, gzip.BadGzipFile)


class LogRecord(NamedTuple):
    """One scan of a log with the robot's raw odometry pose at it (None where the log has no
    odometry) and, for a simulated log, the true pose (else None). The scan's
    ``sensor_pose`` is the laser's mounting pose on the robot."""

    scan: LaserScan
    odometry: Pose2D | None
    truth: Pose2D | None = None


# -- errors --------------------------------------------------------------------------------
class LogFormatError(FuzzyposError, ValueError):
    """A malformed line in a log file: ``"<file>:<line>: <what>"``.

    ``path`` is the file as given, ``line`` the 1-based line number (0 when the problem is
    not on one line) and ``reason`` what is wrong.
    """

    def __init__(self, path: PathLike, line: int, reason: str) -> None:
        self.path = display_name(path)
        self.line = int(line)
        self.reason = reason
        where = f"{self.path}:{self.line}" if self.line > 0 else self.path
        super().__init__(f"{where}: {reason}")

    def __reduce__(self) -> tuple[type, tuple[str, int, str]]:  # picklable across processes
        return (type(self), (self.path, self.line, self.reason))

    def worded(self, names: Mapping[str, str]) -> str:
        where = f"{self.path}:{self.line}" if self.line > 0 else self.path
        return f"{where}: {worded(self.reason, names)}"


def numeric_rows(
    path: PathLike, names: tuple[str, ...], error: type[LogFormatError]
) -> Iterator[tuple[int, list[float]]]:
    """``(line number, values)`` for every line of a text file (plain or gzip) holding exactly
    ``len(names)`` finite numbers; ``#`` comments and blank lines are skipped. Anything else
    raises ``error`` naming the file, the line and the field (by ``names``), and so does a
    damaged gzip stream (cut short, corrupt), naming the line it stopped at."""
    with open_text(path) as fh:
        for lineno, line in _lines(fh, path, error):
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


def _lines(fh: IO[str], path: PathLike, error: type[LogFormatError]) -> Iterator[tuple[int, str]]:
    """The 1-based numbered lines of ``fh``; a damaged gzip stream raises ``error``."""
    it = iter(fh)
    lineno = 0
    while True:
        try:
            line = next(it)
        except StopIteration:
            return
        except GZIP_ERRORS as exc:
            what = "ends early" if isinstance(exc, EOFError) else "is corrupt"
            raise error(
                path, lineno + 1, f"the gzip stream {what} ({exc}): the file is damaged"
            ) from None
        lineno += 1
        yield lineno, line


# -- files ---------------------------------------------------------------------------------
def open_text(path: PathLike) -> IO[str]:
    """Open a text log for reading, decompressing gzip when the file starts with its magic
    bytes (whatever its name). The file is opened once and its first bytes put back, so a
    pipe or FIFO (``<(zcat log.gz)``, ``/dev/stdin``) reads whole. A UTF-8 byte order mark
    at the start is dropped (editors on Windows write one). Undecodable bytes become U+FFFD
    (and fail to parse as numbers rather than aborting the read)."""
    f = open(path, "rb")  # noqa: SIM115 - closed with the returned stream
    try:
        magic = f.read(2)
        binary: IO[bytes] = f
        if f.seekable():
            f.seek(0)
        else:  # a pipe: the bytes read cannot be sought back to
            binary = cast(IO[bytes], io.BufferedReader(_Rewound(magic, f)))
        if magic != GZIP_MAGIC:
            return _TextLog(binary)
        gz = gzip.GzipFile(filename=display_name(path), mode="rb", fileobj=binary)
        # GzipFile leaves a file object it was given open: the text stream closes it
        return _TextLog(cast(IO[bytes], gz), also_close=binary)
    except BaseException:
        f.close()
        raise


class _TextLog(io.TextIOWrapper):
    """UTF-8 text (a leading byte order mark dropped, undecodable bytes replaced) over a byte
    stream, closing ``also_close`` (the file under a gzip layer) with itself."""

    def __init__(self, raw: IO[bytes], also_close: IO[bytes] | None = None) -> None:
        super().__init__(raw, encoding="utf-8-sig", errors="replace")
        self._also_close = also_close

    def close(self) -> None:
        try:
            super().close()
        finally:
            if self._also_close is not None:
                self._also_close.close()


class _Rewound(io.RawIOBase):
    """A stream that cannot seek (a pipe) with its first bytes, already read, put back."""

    def __init__(self, head: bytes, rest: IO[bytes]) -> None:
        super().__init__()
        self._head = head
        self._rest = rest

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")
        if self._head:
            n = min(len(view), len(self._head))
            view[:n] = self._head[:n]
            self._head = self._head[n:]
            return n
        data = self._rest.read(len(view))
        view[: len(data)] = data
        return len(data)

    def close(self) -> None:
        try:
            self._rest.close()
        finally:
            super().close()


# -- pipes -----------------------------------------------------------------------------------
def is_stream(path: PathLike) -> bool:
    """Whether ``path`` is something that can be read only once: a pipe, a FIFO, a terminal
    (``<(zcat log.gz)``, ``/dev/stdin``), i.e. it exists and is neither a regular file nor a
    directory."""
    if isinstance(path, Spool):
        return False
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


class Spool(os.PathLike[str]):
    """A log read from a pipe, copied once into a temporary file so that it can be read again
    (sniffed, counted, streamed, hashed). It opens as that file (``os.fspath``) but is named as
    the input given (``str``, :attr:`name`, and in every error message, see
    :func:`display_name`). A stream whose first KiB holds a NUL byte but is neither gzip nor a
    ROS1 bag (``/dev/zero``, which never ends) is refused at once with a
    :class:`LogFormatError`. The file is removed when the spool is garbage collected (or the
    interpreter exits)."""

    def __init__(self, path: PathLike) -> None:
        self.name = os.fspath(path)
        with open(path, "rb") as src:
            head = src.read(_SNIFF_STREAM)
            _check_stream_head(path, head)
            fd, tmp = tempfile.mkstemp(prefix="fuzzypos-spool-")
            self.file = tmp
            self._remove = weakref.finalize(self, _unlink, tmp)
            with os.fdopen(fd, "wb") as dst:
                dst.write(head)
                shutil.copyfileobj(src, dst, 1 << 20)

    def __fspath__(self) -> str:
        return self.file

    def __str__(self) -> str:
        return self.name

    def __repr__(self) -> str:
        return f"Spool({self.name!r})"


#: how many leading bytes of a stream are looked at before it is copied (:class:`Spool`)
_SNIFF_STREAM = 1024

#: what a ROS1 bag starts with (:mod:`fuzzypos.io.rosbag` has it too)
_ROS1_MAGIC = b"#ROSBAG V2.0"


def _check_stream_head(path: PathLike, head: bytes) -> None:
    """Refuse a stream whose first bytes are binary but neither gzip nor a ROS1 bag (a NUL
    byte in its first KiB): a device such as ``/dev/zero`` never ends, so it must be refused
    before it is copied. :class:`LogFormatError` naming it."""
    if b"\x00" in head and not head.startswith((GZIP_MAGIC, _ROS1_MAGIC)):
        raise LogFormatError(
            path,
            0,
            f"not a log: binary content (a NUL byte in its first {len(head)} bytes) that is "
            "neither gzip, a ROS1 bag nor a CARMEN text log",
        )


def _unlink(path: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


def spool_if_stream(path: PathLike) -> PathLike:
    """``path`` itself, or a :class:`Spool` of it when it can be read only once
    (:func:`is_stream`); for readers that read their input more than once."""
    return Spool(path) if is_stream(path) else path


def display_name(path: PathLike) -> str:
    """The name to show for ``path``: the input given, also for a :class:`Spool` of it."""
    return path.name if isinstance(path, Spool) else os.fspath(path)


# -- outputs ---------------------------------------------------------------------------------
class OutputPathError(FuzzyposError, OSError):
    """An output path that fuzzypos will not write (a socket, a block device, a folder where a
    file is wanted, one it cannot create or replace): ``"<path>: <why>"``, found before a
    run starts."""

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


class OutputWriteError(FuzzyposError, OSError):
    """Writing an output failed (a full disk, a closed pipe): ``"cannot write <path>: <why>"``
    (``errno`` the failure's, ``filename`` the path as given)."""

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


def output_target(path: PathLike) -> tuple[Path, bool]:
    """Where writing ``path`` goes, and whether it is streamed: a pipe, a FIFO or a character
    device (``>(cat > x)``, ``/dev/stdout``, ``/dev/null``) is written to directly and never
    replaced (``(path, True)``); a regular file or a new path is written where it points,
    through symlinks (``(its target, False)``: replaced atomically in the target's folder).
    Anything else (a folder, a socket, a block device, a path it cannot look at) is an
    :class:`OutputPathError` (a folder an ``IsADirectoryError``)."""
    name = os.fspath(path)
    try:
        mode: int | None = os.stat(name).st_mode
    except FileNotFoundError:
        mode = None  # a new path (or a link to one): written where it points
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        if isinstance(exc, NotADirectoryError):
            why = "a part of the path is a file, not a folder"
        raise OutputPathError(exc.errno, f"cannot be written: {why}", name) from None
    if mode is not None and (stat.S_ISFIFO(mode) or stat.S_ISCHR(mode)):
        return Path(name), True
    if mode is not None and stat.S_ISDIR(mode):
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", name)
    if mode is not None and not stat.S_ISREG(mode):
        what = "a socket" if stat.S_ISSOCK(mode) else "a block device or other special file"
        raise OutputPathError(
            errno.EINVAL, f"is {what}, not a file, a pipe or a character device", name
        )
    return Path(os.path.realpath(name)), False


def check_output_file(path: PathLike) -> tuple[Path, bool]:
    """:func:`output_target`, and that it can be written: a streamed target writable, else
    its folder existing and a file creatable there (tried: a read-only folder or file system
    is an :class:`OutputPathError`; no folder a ``FileNotFoundError``)."""
    name = os.fspath(path)
    target, streamed = output_target(path)
    if streamed:
        if not os.access(target, os.W_OK):
            raise OutputPathError(errno.EACCES, "cannot be written: permission denied", name)
        return target, streamed
    folder = target.parent
    if not folder.is_dir():
        if folder.exists():
            why = f"cannot be written: {os.fspath(folder)} is a file, not a folder"
            raise OutputPathError(errno.ENOTDIR, why, name)
        raise FileNotFoundError(
            errno.ENOENT, f"cannot be written: no folder {os.fspath(folder)}", name
        )
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".probe", dir=folder)
    except OSError as exc:
        why = (
            f"{os.fspath(folder)} is read-only"
            if exc.errno in (errno.EACCES, errno.EROFS)
            else (exc.strerror or type(exc).__name__)
        )
        raise OutputPathError(exc.errno, f"cannot be written: {why}", name) from None
    os.close(fd)
    _unlink(probe)
    return target, streamed


@contextlib.contextmanager
def _naming(path: PathLike, *also: PathLike) -> Iterator[None]:
    """An ``OSError`` of writing (one without a file name, or naming ``also``, the temporary
    file) as an :class:`OutputWriteError` naming ``path``."""
    try:
        yield
    except OutputWriteError:
        raise
    except OSError as exc:
        named = exc.filename
        if named is not None and os.fspath(named) not in {os.fspath(a) for a in also}:
            raise
        why = exc.strerror or str(exc) or type(exc).__name__
        raise OutputWriteError(exc.errno, why, display_name(path)) from exc


def _write_to(target: PathLike, gz: bool, write: Callable[[IO[str]], None]) -> None:
    if gz:
        with (
            open(target, "wb") as raw,
            gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gzf,
            io.TextIOWrapper(gzf, encoding="utf-8", newline="\n") as fh,
        ):
            write(fh)
    else:
        with open(target, "w", encoding="utf-8", newline="\n") as fh:
            write(fh)


def _write_atomically(path: PathLike, write: Callable[[IO[str]], None]) -> None:
    """Call ``write`` on a text stream that ends up where ``path`` points
    (:func:`output_target`): streamed to a pipe or character device; else a temporary file
    next to the target is renamed over it only if ``write`` returns, or removed. A name
    ending in ``.gz`` gets a gzip file. A failure to write is an :class:`OutputWriteError`."""
    target, streamed = output_target(path)
    gz = os.fspath(path).endswith(".gz")
    if streamed:
        with _naming(path, target):
            _write_to(target, gz, write)
        return
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        with _naming(path, tmp, target):
            _write_to(tmp, gz, write)
            os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_text_file(path: PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) where ``path`` points, as :func:`_write_atomically` does."""

    def write(fh: IO[str]) -> None:
        fh.write(text)

    _write_atomically(path, write)
