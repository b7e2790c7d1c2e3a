"""Results folders: their names (:func:`log_name`, :func:`default_results_dir`), the rule
that one holds one run (:class:`ResultsFolder`, :class:`ResultsFolderError`), and the check
of a run's output paths before it starts (:func:`check_outputs`).

A run's folder is new (by default ``results/<log>/<date-time>/``, with ``results/<log>/latest``
linked to the newest), empty, or one holding another run's results, which is refused unless
``overwrite``: then it is cleared first, but only where it is fuzzypos's (its
``summary.json`` or ``config.toml`` is) and holds nothing else. A run locks its folder
(:meth:`ResultsFolder.make`, an ``flock`` on ``.fuzzypos.lock`` in it, which holds the run's
pid) until it ends: a second run into it is a :class:`ResultsFolderBusyError`. A folder the
run cannot create a file in is an :class:`~fuzzypos.io.OutputPathError`.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from ..config import Config
from ..errors import FuzzyposError
from ..io import OutputPathError, check_output_file

__all__ = [
    "RESULT_FILES",
    "ResultsFolder",
    "ResultsFolderBusyError",
    "ResultsFolderError",
    "check_outputs",
    "default_results_dir",
    "log_name",
]

#: compression suffixes :func:`log_name` strips
_COMPRESSION_SUFFIXES = (".gz", ".bz2", ".xz", ".zst", ".lz4")
#: format suffixes :func:`log_name` strips too, unless ``keep_format``
_FORMAT_SUFFIXES = (".clf", ".log", ".bag", ".carmen")

#: the files of a results folder (:func:`~fuzzypos.jobs.run.run_log`)
RESULT_FILES = (
    "trajectory.tum",
    "trajectory.clf",
    "config.toml",
    "path.png",
    "covariance.csv",
    "summary.json",
    # with loop closure (fuzzypos.graph.LOOP_CLOSURE_FILES)
    "trajectory_frontend.tum",
    "covariance_optimised.csv",
    "trajectory_online.tum",
    "graph.g2o",
    "map.pgm",
    "map.yaml",
    "map.png",
)
#: the lock file of a results folder in use (hidden: never a result)
LOCK_FILE = ".fuzzypos.lock"
#: the default results folder's name: the run's local date and time
_DATE_TIME = "%Y-%m-%d_%H-%M-%S"


def log_name(path: str | os.PathLike[str], *, keep_format: bool = False) -> str:
    """A log's file name without a compression suffix and without its format's: the name its
    relations are found by (``intel.clf.gz`` → ``intel``, ``aces.bag`` → ``aces``). With
    ``keep_format`` the format's suffix stays, naming its folders of results and plots
    (``data/aces.clf.gz`` → ``aces.clf``, ``aces.bag`` → ``aces.bag``). A folder (a ROS2
    bag) is its name: ``my_bag/`` → ``my_bag``."""
    name = Path(path).name or Path(os.path.abspath(path)).name
    name = _without_suffix(name, _COMPRESSION_SUFFIXES)
    return name if keep_format else _without_suffix(name, _FORMAT_SUFFIXES)


def _without_suffix(name: str, suffixes: tuple[str, ...]) -> str:
    """``name`` without the first of ``suffixes`` it ends in (any case), unless that is all
    of it."""
    for suffix in suffixes:
        if name.lower().endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return name


def default_results_dir(path: str | os.PathLike[str], when: float | None = None) -> Path:
    """``results/<log>/<date-time>/``, relative to the working directory (``<log>``:
    :func:`log_name` with ``keep_format``; the local time ``when``, default now, as
    ``2024-05-01_13-45-07``).
    :meth:`ResultsFolder.make` creates it (adding ``-2``, ``-3`` … where it exists)."""
    stamp = time.strftime(_DATE_TIME, time.localtime(when))
    return Path("results") / log_name(path, keep_format=True) / stamp


class ResultsFolderError(FuzzyposError, FileExistsError):
    """A results folder that a run will not write into (or clear): ``"<folder>: <why>"``."""

    def __init__(self, folder: str | os.PathLike[str], reason: str) -> None:
        super().__init__(errno.EEXIST, reason, os.fspath(folder))

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


class ResultsFolderBusyError(ResultsFolderError):
    """A results folder another run is writing (it holds the folder's lock):
    ``"results folder <folder> is in use by another run (pid <pid>)"``."""

    def __init__(self, folder: str | os.PathLike[str], pid: int | None) -> None:
        self.pid = pid
        who = "another run" + ("" if pid is None else f" (pid {pid})")
        super().__init__(folder, f"is in use by {who}")
        self.errno = errno.EBUSY

    def __str__(self) -> str:
        return f"results folder {self.filename} {self.strerror}"


def _holder(fd: int) -> int | None:
    """The pid written in a lock file (None where unreadable: its run is just starting)."""
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _lock(folder: Path) -> int:
    """Take ``folder``'s lock (:data:`LOCK_FILE`, ``flock``, its pid written in it): the open
    descriptor. Held: :class:`ResultsFolderBusyError`; no file can be created there:
    :class:`~fuzzypos.io.OutputPathError`."""
    path = folder / LOCK_FILE
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            why = exc.strerror or type(exc).__name__
            raise OutputPathError(
                exc.errno, f"cannot be written: {why}", os.fspath(folder)
            ) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            pid = _holder(fd)
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise ResultsFolderBusyError(folder, pid) from None
            raise
        try:  # its last owner may have removed it between our open and our lock
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode("ascii"))
            return fd
        os.close(fd)


def _visible(folder: Path) -> list[str]:
    """The names in ``folder`` but hidden ones (``.x``: ours are temporary files)."""
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))


def _listed(folder: Path) -> tuple[bool, set[str]]:
    """Whether ``folder``'s ``summary.json`` is fuzzypos's, and the names of the files it
    lists in the folder (e.g. an ``out_tum`` written there)."""
    try:
        data = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False, set()
    if not isinstance(data, dict) or "fuzzypos_version" not in data:
        return False, set()
    files = data.get("files")
    if not isinstance(files, dict) or not isinstance(files.get("summary.json"), str):
        return True, set()
    home = Path(files["summary.json"]).parent  # the folder as that run named it
    paths = [Path(v) for v in files.values() if isinstance(v, str)]
    return True, {p.name for p in paths if p.parent == home}


def _is_our_config(path: Path) -> bool:
    try:
        Config.from_toml(path)
    except (OSError, ValueError):
        return False
    return True


def _clear_for_a_run(folder: Path, overwrite: bool) -> None:
    """Check that ``folder`` (an existing directory) may get a run's results: it is empty,
    or, with ``overwrite``, a fuzzypos results folder, which is then cleared."""
    names = _visible(folder)
    ours = [n for n in RESULT_FILES if n in names]
    if names and not ours:
        shown = ", ".join(names[:3]) + (" …" if len(names) > 3 else "")
        raise ResultsFolderError(
            folder, f"is not empty ({shown}) and not a results folder; give a new or empty one"
        )
    if not ours:
        return
    if not overwrite:
        raise ResultsFolderError(
            folder,
            f"holds the results of another run ({', '.join(ours)}); give a new folder, or "
            "overwrite them (fuzzypos run --overwrite)",
        )
    summary_ok, listed = _listed(folder)
    if not summary_ok and not ("config.toml" in ours and _is_our_config(folder / "config.toml")):
        raise ResultsFolderError(
            folder, "has no fuzzypos summary.json or config.toml: not clearing it"
        )
    others = [n for n in names if n not in RESULT_FILES and n not in listed]
    if others:
        raise ResultsFolderError(
            folder, f"holds files fuzzypos did not write ({', '.join(others)}): not clearing it"
        )
    for name in [*ours, *(n for n in names if n in listed and n not in RESULT_FILES)]:
        target = folder / name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        else:
            target.unlink()
    for pattern in (".*.tmp", ".*.part"):  # what a killed run may have left
        for stale in folder.glob(pattern):
            stale.unlink(missing_ok=True)


def _mkdirs(folder: Path) -> list[Path]:
    """Create ``folder`` (``FileExistsError`` where it exists) and its missing parents; the
    folders created, innermost first."""
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True)
    return missing


@dataclass(eq=False)
class ResultsFolder:
    """The results folder of a run: where, which folders the run created (removed again when
    it keeps nothing) and whether it is the default (then ``latest`` links to it)."""

    path: Path
    created: list[Path]
    default: bool
    #: the lock's descriptor while the run holds the folder (:meth:`release`)
    lock: int | None = None

    @classmethod
    def make(
        cls, log: str | os.PathLike[str], results_dir: Path | None, overwrite: bool
    ) -> ResultsFolder:
        """The folder for a run of ``log``: ``results_dir`` (checked, cleared with
        ``overwrite``, created where missing), or a new default one; locked by this run
        (before it is cleared) until :meth:`release` (the end of a ``with`` block) or the
        process's end."""
        if results_dir is None:
            first = default_results_dir(log)
            for k in range(1, 1000):
                cand = first if k == 1 else first.with_name(f"{first.name}-{k}")
                with contextlib.suppress(FileExistsError):
                    return cls(cand, _mkdirs(cand), True)._locked()
            raise ResultsFolderError(first, "exists, and so do 998 more of its names")
        if results_dir.is_dir():
            folder = cls(results_dir, [], False)._locked()
            try:
                _clear_for_a_run(results_dir, overwrite)
            except BaseException:
                folder.release()
                raise
            return folder
        if results_dir.exists() or results_dir.is_symlink():
            raise NotADirectoryError(errno.ENOTDIR, "is not a folder", os.fspath(results_dir))
        return cls(results_dir, _mkdirs(results_dir), False)._locked()

    def _locked(self) -> ResultsFolder:
        try:
            self.lock = _lock(self.path)
        except BaseException:
            self.discard()
            raise
        return self

    def release(self) -> None:
        """Give the folder up: remove its lock file and unlock it (again: nothing)."""
        if self.lock is None:
            return
        fd, self.lock = self.lock, None
        with contextlib.suppress(OSError):
            (self.path / LOCK_FILE).unlink()  # while still locked: no one else holds it
        os.close(fd)

    def __enter__(self) -> ResultsFolder:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.release()

    def discard(self) -> None:
        """Release the folder, and remove the folders the run created, where they are
        empty."""
        self.release()
        for d in self.created:
            with contextlib.suppress(OSError):
                d.rmdir()

    def link_latest(self) -> None:
        """``<log>/latest`` → this folder (a relative link), for a default folder; quietly
        nothing where the file system has no links."""
        if not self.default:
            return
        tmp = self.path.parent / f".latest.{os.getpid()}.tmp"
        try:
            tmp.unlink(missing_ok=True)
            os.symlink(self.path.name, tmp, target_is_directory=True)
            os.replace(tmp, self.path.parent / "latest")
        except OSError:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)


def check_outputs(
    folder: Path | None,
    out_tum: str | os.PathLike[str] | None,
    bag_out: str | os.PathLike[str] | None,
) -> None:
    """Fail before the run, not after it, on an output path that cannot be written: a
    ``folder`` that is not one (or lies under a file), an ``out_tum`` that is not a regular
    file, a new path, a pipe or a character device, or cannot be created
    (:func:`~fuzzypos.io.check_output_file`), a ``bag_out`` that exists or whose folder
    cannot be."""
    if folder is not None:
        _check_folder(folder)
    if out_tum is not None:
        tum = Path(out_tum)
        parent = tum.parent
        in_results = folder is not None and parent.absolute() == folder.absolute()
        if tum.is_dir():
            raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", os.fspath(tum))
        if not in_results or folder is None or folder.is_dir():
            check_output_file(tum)
    if bag_out is not None:
        if Path(bag_out).exists() or Path(bag_out).is_symlink():
            raise FileExistsError(
                errno.EEXIST, "exists already; a bag is never overwritten", os.fspath(bag_out)
            )
        _check_folder(Path(bag_out).parent, os.fspath(bag_out))


def _check_folder(folder: Path, name: str | None = None) -> None:
    """That ``folder``, or where missing its nearest existing parent, is a folder (``name``:
    the output path to name, default ``folder``)."""
    for at in (folder.absolute(), *folder.absolute().parents):
        if at.exists() or at.is_symlink():
            if at.is_dir():
                return
            if name is None and at == folder.absolute():
                raise NotADirectoryError(errno.ENOTDIR, "is not a folder", os.fspath(folder))
            why = f"cannot be written: {os.fspath(at)} is a file, not a folder"
            raise OutputPathError(errno.ENOTDIR, why, os.fspath(folder) if name is None else name)
