"""Part of the command line (:mod:`fuzzypos.cli`): its help as it is shown (the commands'
classes), ``--version``, ``run``'s map flags, and the notice while the kernels compile."""

from __future__ import annotations

import inspect
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from typing import Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import Progress
from typer.core import TyperArgument, TyperCommand, TyperGroup
from typer.models import CommandInfo

from .._version import __version__
from ..config import Config, ConfigError

__all__ = [
    "BATCH_HELP",
    "BATCH_OPTIONS",
    "COMPILING",
    "RUN_OPTIONS",
    "VERSION",
    "Command",
    "Group",
    "compiling_shown",
    "escape_markup",
    "finish_command",
]


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"fuzzypos {__version__}")
        raise typer.Exit()


#: ``fuzzypos --version``
VERSION = typer.Option(
    "--version", callback=_print_version, is_eager=True, help="print the version and exit"
)


def escape_markup(command: Any) -> None:
    """Escape a click command's help and its options' and arguments' (a group's commands'
    too) for rich's markup, in which typer shows them: ``[graph]`` in ``pip install
    'fuzzypos[graph]'`` would be taken for a style and dropped. Once per command object
    (typer builds them afresh for each invocation, from the same texts)."""
    if getattr(command, "_markup_escaped", False):
        return
    command._markup_escaped = True
    for name in ("help", "short_help"):
        text = getattr(command, name, None)
        if text:
            setattr(command, name, escape(text))
    for param in getattr(command, "params", ()):
        if getattr(param, "help", None):
            param.help = escape(param.help)
    for sub in getattr(command, "commands", {}).values():
        escape_markup(sub)


class _Plain:
    """Flags in the help without typer's ``<bool>`` (it shows a metavar in place of the type);
    ``[...]`` in the help shown, not taken for rich's markup."""

    def format_help(self, ctx: Any, formatter: Any) -> None:
        if getattr(self, "rich_markup_mode", None) == "rich":
            escape_markup(self)
        super().format_help(ctx, formatter)  # type: ignore[misc]

    def get_params(self, ctx: Any) -> list[Any]:
        params: list[Any] = super().get_params(ctx)  # type: ignore[misc]
        for p in params:
            if getattr(p, "is_flag", False) and p.metavar is None:
                p.metavar = ""
        return params


class Group(_Plain, TyperGroup):
    pass


class Command(_Plain, TyperCommand):
    """A command whose usage line names its arguments ``LOG``, not typer's ``{log}``."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        pieces = [self.options_metavar] if self.options_metavar else []
        for p in self.get_params(ctx):
            if isinstance(p, TyperArgument):
                name = (p.metavar or p.name or "").upper() + ("..." if p.nargs != 1 else "")
                pieces.append(name if p.required else f"[{name}]")
            else:
                pieces.extend(p.get_usage_pieces(ctx))
        return pieces


#: ``fuzzypos batch``'s help
BATCH_HELP = (
    "Every log under PATHS × every --config, a Ray task each: OUT/<log>/<config>/, batch.json."
    "\n\nA complete run made alike is skipped, one made otherwise refused unless --force; an "
    "unreadable file named as a log (.clf, .clf.gz, .log, .bag) fails. Exit 1 where a run "
    'failed or was refused, 130 on Ctrl-C (batch.json\'s "interrupted"), 2 on bad input.'
)
#: ``fuzzypos batch``'s flags
BATCH_OPTIONS = {
    "loop_closure": typer.Option("--loop-closure", help="close loops in every run (as run's)"),
    "force": typer.Option("--force", help="redo complete runs, those made otherwise too"),
    "verbose": typer.Option("--verbose", help="Ray's own log lines too"),
}


def _check_map_resolution(value: float | None) -> float | None:
    """``--map-resolution`` within ``[loop_closure] map_resolution``'s bounds, else one line
    and exit 2 (before the log is opened)."""
    if value is not None:
        try:
            Config().with_overrides({"loop_closure": {"map_resolution": value}})
        except ConfigError as exc:
            why = str(exc).replace("loop_closure.map_resolution", "--map-resolution (m)")
            typer.echo(f"fuzzypos: error: {why}", err=True)
            raise typer.Exit(code=2) from None
    return value


#: ``fuzzypos run``'s map and bag flags
RUN_OPTIONS = {
    "loop_closure": typer.Option(
        "--loop-closure",
        help="close loops online on a pose graph of the keyframes ([loop_closure], needs "
        "pip install 'fuzzypos[graph]'): trajectory.tum optimised, trajectory_frontend.tum, "
        "trajectory_online.tum (each scan's pose as first output), graph.g2o, "
        "map.pgm/map.yaml/map.png (the optimised map), the closures in summary.json",
    ),
    "save_map": typer.Option(
        "--save-map",
        help="also write the occupancy map map.pgm/map.yaml (ROS map_server) and map.png, "
        "drawn from the front end's poses (no gtsam needed; with --loop-closure its optimised "
        "map is written)",
    ),
    "map_resolution": typer.Option(
        "--map-resolution",
        help="the map's cell size in metres (default [loop_closure] map_resolution, 0.05; "
        "0.01 to 10)",
        callback=_check_map_resolution,
    ),
    "bag_out": typer.Option(
        "--bag-out",
        help="also write the estimate into this new bag: nav_msgs/Odometry on /fuzzypos/odom "
        "and odom → base on /tf; with --loop-closure the optimised poses on /fuzzypos/pose and "
        "map → odom on /tf (a name ending .bag: ROS1, else a ROS2 directory); an existing path "
        "is refused",
        readable=False,
    ),
    "bag_storage": typer.Option(
        "--bag-storage", help="ros1, sqlite3 or mcap (default: by --bag-out's name)"
    ),
    "base_frame": typer.Option(
        "--base-frame",
        help="--bag-out's robot frame (default: the input bag's odometry child_frame_id, else "
        "base_link); a bag's laser mounting is looked up from it",
    ),
    "odom_frame": typer.Option(
        "--odom-frame",
        help="--bag-out's odometry frame (default: the input bag's odometry header.frame_id, "
        "else odom)",
    ),
    "map_frame": typer.Option(
        "--map-frame",
        help="--bag-out's map frame (default: the odometry frame's parent on the input bag's "
        "/tf, else map)",
    ),
}


def _unwrap(doc: str) -> str:
    """A docstring as help text: the lines of each paragraph joined (typer's rich help keeps
    the docstring's line breaks otherwise)."""
    paragraphs = inspect.cleandoc(doc).split("\n\n")
    return "\n\n".join(" ".join(p.split()) for p in paragraphs)


def finish_command(command: CommandInfo) -> None:
    """A command as registered: its help from its docstring, unwrapped (where not given), and
    its class :class:`Command`."""
    if command.help is None and command.callback is not None and command.callback.__doc__:
        command.help = _unwrap(command.callback.__doc__)
    if command.cls in (None, TyperCommand):
        command.cls = Command


#: said once, on stderr, where the kernels' cache is cold (before they compile)
COMPILING = "compiling the kernels on first use (a minute or two; cached afterwards)…"


@contextmanager
def compiling_shown(console: Console, progress: Progress | None = None) -> Iterator[None]:
    """While the kernels compile (``compiling`` of :func:`~fuzzypos.jobs.run.run_log`): the line
    :data:`COMPILING` on ``console`` (stderr), then on a terminal a spinner: a task of
    ``progress`` where that display is live (rich shows one live display at a time), else
    the console's status."""
    console.print(COMPILING, highlight=False, markup=False, soft_wrap=True)
    if progress is None:
        with console.status("compiling the kernels") if console.is_terminal else nullcontext():
            yield
        return
    task = progress.add_task("compiling the kernels", total=None)
    try:
        yield
    finally:
        progress.remove_task(task)
