"""Part of the command line (:mod:`fuzzypos.cli`): the typer ``app`` the commands register
on (``from .app import app`` then ``@app.command()``), the one place their errors become one
line and an exit code (:func:`launch`), and what the commands share: the options of a log,
the configuration, the consoles.

A command does its work and lets a library error (:class:`~fuzzypos.errors.FuzzyposError`,
``ValueError``, ``OSError``) or Ctrl-C through; :func:`launch` turns it into
``fuzzypos: error: <one line>`` (exit 2) or ``fuzzypos: interrupted…`` (exit 130), with what
a stopped run kept. The library's arguments named in a message (``max_scans``) are said as
the flags that set them (``--max-scans``, :data:`FLAGS`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn, TypeVar

import typer
from rich.console import Console
from rich.progress import Progress
from typer.models import CommandFunctionType

from ..config import Config
from ..errors import FuzzyposError
from .help import VERSION, Command, Group, finish_command

if TYPE_CHECKING:
    from ..io import OpenLog

__all__ = [
    "CONFIG_FILE",
    "CONVENTION",
    "FLAGS",
    "FOV",
    "JSON",
    "LASER_OFFSET",
    "LOG_ARG",
    "MAX_RANGE",
    "ODOMETRY",
    "ODOM_TOPIC",
    "PRESET",
    "SCAN_RATE",
    "SCAN_TOPIC",
    "SKIP_BAD",
    "App",
    "LaunchingGroup",
    "app",
    "console",
    "err_console",
    "error_text",
    "fail",
    "kept_on_interrupt",
    "launch",
    "load_config",
    "main",
    "open_log",
    "print_warnings",
    "progress_display",
    "wide",
]

T = TypeVar("T")

console = Console()
err_console = Console(stderr=True)

#: the library's argument names as the command line's flags (for the messages that name them)
FLAGS = {
    "field_of_view_deg": "--fov",
    "max_scans": "--max-scans",
    "scan_topic": "--scan-topic",
    "odom_topic": "--odom-topic",
    "max_range": "--max-range",
    "laser_offset": "--laser-offset",
    "convention": "--convention",
    "odometry": "--odometry",
    "start": "--start",
    "end": "--end",
    "scan_rate_hz": "--scan-rate",
    "jobs": "--jobs",
}


def fail(message: str, code: int = 2) -> NoReturn:
    """``fuzzypos: error: <message>`` on stderr, and exit ``code``."""
    typer.echo(f"fuzzypos: error: {message}", err=True)
    raise typer.Exit(code=code)


def error_text(exc: BaseException) -> str:
    """One line for a library or file-system error, its arguments named as flags (a run's that
    stopped it, for a partial run)."""
    from ..jobs.run import PartialRunError

    if isinstance(exc, PartialRunError):
        exc = exc.stopped
    if isinstance(exc, OSError) and type(exc).__str__ is not OSError.__str__:
        return " ".join(str(exc).split())  # a typed error that words itself
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    text = exc.worded(FLAGS) if isinstance(exc, FuzzyposError) else str(exc)
    return " ".join(text.split()) or type(exc).__name__  # one line


def launch(command: Callable[[], T]) -> T:
    """``command()``, its errors said once: a library error (``FuzzyposError``, ``ValueError``,
    ``OSError``) as one line and exit 2, Ctrl-C (numba's ``SystemError`` around it too) as
    ``fuzzypos: interrupted`` and exit 130; each followed by what a stopped run kept (or, on
    Ctrl-C, what the command said it keeps: :func:`kept_on_interrupt`)."""
    from ..jobs.outputs import as_interrupt, is_interrupt

    said = _KEPT.set(None)
    try:
        return command()
    except (KeyboardInterrupt, SystemError) as exc:
        if not is_interrupt(exc):
            raise
        text = _KEPT.get()
        kept = f"; {text}" if text else _kept(as_interrupt(exc))
        typer.echo(f"fuzzypos: interrupted{kept}", err=True)
        raise typer.Exit(code=130) from None
    except (FuzzyposError, ValueError, OSError) as exc:
        fail(error_text(exc) + _kept(exc))
    finally:
        _KEPT.reset(said)


#: what the running command keeps on Ctrl-C (:func:`kept_on_interrupt`)
_KEPT: ContextVar[str | None] = ContextVar("kept_on_interrupt", default=None)


def kept_on_interrupt(text: str) -> None:
    """Say what the running command keeps if Ctrl-C stops it (``the runs finished are in
    out/batch.json``), for :func:`launch`'s line."""
    _KEPT.set(text)


def _kept(exc: BaseException) -> str:
    """What a run stopped by ``exc`` kept, as the end of its one line."""
    from ..jobs.run import partial_results

    kept = partial_results(exc)
    if kept is None:
        return "; nothing kept" if isinstance(exc, KeyboardInterrupt) else ""
    marked = (
        '(summary.json: "partial": true)'
        if "summary.json" in kept.files
        else "(summary.json could not be written)"
    )
    reason = kept.partial_reason or ""
    if reason.startswith(("interrupted at scan", "failed at scan")):  # in the loop
        where = f"the {kept.scans} scans before it are kept in {kept.results_dir}/ {marked}"
        if isinstance(exc, KeyboardInterrupt):
            return f" at scan {kept.scans + 1}; {where}"
        return f" (stopped at scan {kept.scans + 1}; {where})"
    where = f"the results of the {kept.scans} scans are kept in {kept.results_dir}/ {marked}"
    if isinstance(exc, KeyboardInterrupt):  # after the loop: where
        return f" {reason.removeprefix('interrupted ')}; {where}"
    return f" (after the {kept.scans} scans; {where})"


class LaunchingGroup(Group):
    """The ``fuzzypos`` group: every command it runs runs under :func:`launch`."""

    def invoke(self, ctx: Any) -> Any:
        return launch(lambda: super(LaunchingGroup, self).invoke(ctx))


class App(typer.Typer):
    """The typer app whose ``@app.command()`` also finishes the command (:func:`finish_command`:
    its help from its docstring, unwrapped; its usage line), whatever module registers it."""

    def command(
        self, name: str | None = None, **kwargs: Any
    ) -> Callable[[CommandFunctionType], CommandFunctionType]:
        kwargs.setdefault("cls", Command)
        register = super().command(name, **kwargs)

        def decorator(f: CommandFunctionType) -> CommandFunctionType:
            register(f)
            finish_command(self.registered_commands[-1])
            return f

        return decorator


app = App(
    cls=LaunchingGroup,
    add_completion=False,
    no_args_is_help=True,
    help="Fuzzy-based positioning from 2D laser scans and odometry.",
)


@app.callback()
def _main(version: Annotated[bool, VERSION] = False) -> None:
    pass


def main() -> None:  # pragma: no cover - console entry point
    app()


# -- what the commands share ----------------------------------------------------------------
PRESET = typer.Option(help="base configuration: default or paper")
CONFIG_FILE = typer.Option("--config", help="TOML file overriding keys", readable=False)


def load_config(preset: str, config: Path | None) -> Config:
    """``--preset``, overridden by ``--config``, loaded as ``Config.from_toml`` loads a file.

    A ``preset = "..."`` line in the file picks the base unless ``--preset`` names another
    than the default (then the two must agree). Keys of older files are read with a warning.
    """
    from ..config.schema import read_toml

    base = Config.preset(preset)
    if config is None:
        return base
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FutureWarning)
        data = read_toml(config)
        cfg = Config.from_dict(data, base=None if preset == "default" else base, source=str(config))
    for w in caught:
        if issubclass(w.category, FutureWarning):
            typer.echo(f"fuzzypos: warning: {w.message}", err=True)
        else:  # pragma: no cover - nothing else warns while loading
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return cfg


def open_log(
    log: Path,
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    laser_offset: str | None = None,
    skip_bad_lines: bool = False,
    odometry: str = "scan",
    fov: float = 180.0,
    max_range: float | None = None,
    convention: str = "auto",
    scan_rate: float | None = None,
    base_frame: str | None = None,
) -> OpenLog:
    """The log, opened with the reader's flags (``--laser-offset`` parsed)."""
    from ..io import open_log as open_any
    from ..io.logs import parse_laser_offset

    offset = None if laser_offset is None else parse_laser_offset(laser_offset)
    return open_any(
        log,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        laser_offset=offset,
        skip_bad_lines=skip_bad_lines,
        odometry=odometry,
        field_of_view_deg=fov,
        max_range=max_range,
        convention=convention,
        scan_rate_hz=scan_rate,
        base_frame=base_frame,
    )


def progress_display() -> Progress:
    """A transient progress display on stderr, shown only on a terminal."""
    return Progress(console=err_console, transient=True, disable=not err_console.is_terminal)


def print_warnings(caught: list[warnings.WarningMessage]) -> None:
    for w in caught:
        typer.echo(f"fuzzypos: warning: {' '.join(str(w.message).split())}", err=True)


def wide() -> Console:
    """The console for tables: the terminal's; a wide one when stdout is a file or pipe (no
    wrapping at 80 columns)."""
    return console if console.is_terminal else Console(width=200)


# the options of a log, as run, info and plot-scan take them
LOG_ARG = typer.Argument(
    help="a CARMEN log (.clf, plain or gzip), a ROS1 bag or a ROS2 bag directory; the kind is "
    "told by content, not by name",
    readable=False,  # the reader's own error is one line, typer's a box
)
SCAN_TOPIC = typer.Option("--scan-topic", help="bags: the LaserScan topic (when several)")
ODOM_TOPIC = typer.Option("--odom-topic", help="bags: the Odometry topic (when several)")
SKIP_BAD = typer.Option(
    "--skip-bad-lines",
    help="CARMEN: skip malformed lines (counted) instead of stopping at the first",
)
ODOMETRY = typer.Option(
    "--odometry",
    help="CARMEN: 'scan' (each scan line's own odometry fields) or 'interpolated' (the ODOM "
    "stream at the scan's stamp)",
)
FOV = typer.Option("--fov", help="CARMEN FLASER: the scanner's field of view (degrees)")
MAX_RANGE = typer.Option(
    "--max-range",
    help="CARMEN: readings at or above it are invalid (default: PARAM robot_front_laser_max, "
    "else learned from the data)",
)
CONVENTION = typer.Option(
    "--convention",
    help="CARMEN FLASER beam angles: auto, resolution (fov/n) or span (fov/(n-1))",
)
LASER_OFFSET = typer.Option(
    "--laser-offset",
    help="the laser's mounting pose on the robot 'x,y,θ' (m, m, degrees); overrides the log's",
)
JSON = typer.Option("--json", help="print JSON instead of a table")
SCAN_RATE = typer.Option(
    "--scan-rate",
    help="take the scans as evenly spaced at this rate (Hz) in file order, stamped k/HZ from 0, "
    "instead of the log's stamps (for a log whose stamps are corrupt)",
)
