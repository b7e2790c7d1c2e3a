"""The command line's frame (:mod:`fuzzypos.cli.app`): a command module registers with
``from .app import app`` and ``@app.command()``; every command's errors are said once, by
:func:`~fuzzypos.cli.app.launch` (one line, exit 2; Ctrl-C exit 130), the library's argument
names as the flags (:class:`fuzzypos.errors.Words`), with no rewriting of other words."""

from __future__ import annotations

import pickle

import pytest
import typer
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.cli.app import FLAGS, App, LaunchingGroup, error_text, launch
from fuzzypos.cli.help import Command
from fuzzypos.errors import Argument, ArgumentError, FuzzyposError, Words
from fuzzypos.io import LogFormatError
from fuzzypos.io.logs import SelectionError

runner = CliRunner()


def test_words_say_the_library_names_or_the_callers() -> None:
    w = Words("pass ", Argument("scan_topic", "="), " to pick one")
    assert w == "pass scan_topic= to pick one"
    assert w.worded({"scan_topic": "--scan-topic"}) == "pass --scan-topic to pick one"
    given = Words(Argument.given("start"), "50 s and ", Argument("end"), " (3 s)")
    assert given == "start=50 s and end (3 s)"
    assert given.worded(FLAGS) == "--start 50 s and --end (3 s)"
    assert given.worded({}) == str(given)  # a name the caller has no word for stays


def test_an_error_of_words_is_worded_and_pickled() -> None:
    exc = SelectionError(Words(Argument("max_scans"), " must be at least 1, got 0"))
    assert isinstance(exc, (ArgumentError, ValueError, FuzzyposError))
    assert str(exc) == "max_scans must be at least 1, got 0"
    assert error_text(exc) == "--max-scans must be at least 1, got 0"
    back = pickle.loads(pickle.dumps(exc))
    assert str(back) == str(exc) and back.worded(FLAGS) == exc.worded(FLAGS)
    log = LogFormatError("a.bag", 0, Words(Argument.given("odom_topic"), "'/x': no such topic"))
    assert str(log) == "a.bag: odom_topic='/x': no such topic"
    assert error_text(log) == "a.bag: --odom-topic '/x': no such topic"
    assert pickle.loads(pickle.dumps(log)).worded(FLAGS) == error_text(log)


def test_a_message_that_names_no_argument_is_left_as_it_is() -> None:
    """Only the arguments a message declares are worded as flags: ``odometry=None`` in prose
    (a plain message) stays, as ``start`` and ``end`` in a file's name do."""
    text = "run.bag: every record has odometry=None; start=2 s end must"
    assert error_text(LogFormatError("x.clf", 3, text)) == f"x.clf:3: {text}"
    assert error_text(ValueError("max_scans must be at least 1")) == "max_scans must be at least 1"


def _fails_with(exc: BaseException) -> typer.Typer:
    """An app (as fuzzypos's) with one command that raises ``exc``."""
    one = App(cls=LaunchingGroup, add_completion=False)

    @one.command()
    def boom() -> None:
        """Raise."""
        raise exc

    @one.command()
    def other() -> None:
        """Nothing."""

    return one


@pytest.mark.parametrize(
    ("exc", "code", "line"),
    [
        (ValueError("bad\n  value"), 2, "fuzzypos: error: bad value"),
        (FileNotFoundError(2, "No such file or directory", "x.clf"), 2,
         "fuzzypos: error: x.clf: No such file or directory"),
        (SelectionError(Words(Argument("end"), " (3 s) must not come before ",
                              Argument("start"), " (5 s)")), 2,
         "fuzzypos: error: --end (3 s) must not come before --start (5 s)"),
        (KeyboardInterrupt(), 130, "fuzzypos: interrupted; nothing kept"),
    ],
)  # fmt: skip
def test_a_command_s_error_is_said_once(exc: BaseException, code: int, line: str) -> None:
    res = runner.invoke(_fails_with(exc), ["boom"])
    assert res.exit_code == code and res.output.splitlines() == [line], res.output


def test_a_bug_is_not_taken_for_bad_input() -> None:
    with pytest.raises(ZeroDivisionError):
        launch(lambda: 1 // 0)
    res = runner.invoke(_fails_with(TypeError("a bug")), ["boom"])
    assert res.exit_code == 1 and isinstance(res.exception, TypeError)


def test_a_command_registered_from_another_module_is_finished() -> None:
    """``@app.command()`` anywhere: the help from the docstring unwrapped, the usage class."""
    one = App(add_completion=False)

    @one.command()
    def look(log: str) -> None:
        """Look at
        a log."""

    info = one.registered_commands[-1]
    assert info.cls is Command and info.help == "Look at a log."
    names = {c.callback.__name__ for c in app.registered_commands if c.callback}
    assert {"run", "info", "plot_scan", "evaluate", "benchmark", "batch", "demo"} <= names
    assert all(c.cls is Command for c in app.registered_commands)
