"""The README stays short and true: its Python example runs on a small simulated log, its
results-folder table names every file a run can write, its command table every command, its
links lead to files that exist, and it holds no machine paths and no issue numbers."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from fuzzypos.cli import app
from fuzzypos.jobs.folders import RESULT_FILES
from helpers import write_sim_log

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _text() -> str:
    return README.read_text(encoding="utf-8")


def _section(title: str) -> str:
    text = _text()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else len(text)]


def python_example() -> str:
    """The README's Python example: the first ```python block of its "Python" section."""
    m = re.search(r"```python\n(.*?)```", _section("Python"), re.S)
    assert m, "no ```python block in the README's Python section"
    return m.group(1)


def test_the_python_example_runs_on_a_simulated_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    code = python_example()
    assert 'open_log("sim.clf")' in code  # the log the example names, written here
    assert len(code.strip().splitlines()) <= 12
    write_sim_log(tmp_path / "sim.clf")
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    scope: dict[str, object] = {"__name__": "readme_example"}
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), scope)
    est = scope["est"]
    # what the example shows: the last estimate's pose, reason and step covariance
    assert est.reason == "matched" and not est.degraded  # type: ignore[attr-defined]
    assert est.covariance.shape == (3, 3)  # type: ignore[attr-defined]
    assert "Pose2D(" in out.getvalue()


def test_the_results_table_names_every_file_a_run_writes() -> None:
    table = _section("The results folder")
    for name in RESULT_FILES:
        assert f"`{name}`" in table, name


def test_the_command_table_names_every_command() -> None:
    commands = {c.name for c in app.registered_commands} | {
        c.callback.__name__.replace("_", "-") for c in app.registered_commands if c.name is None
    }
    commands.discard(None)
    assert len(commands) >= 9, commands
    table = _section("Commands")
    for name in commands:
        assert f"| `{name}` |" in table, name


def test_the_set_up_commands_come_first() -> None:
    first_block = _text().split("```")[1]
    assert first_block.splitlines()[1].startswith("make demo")
    assert first_block.splitlines()[2].startswith("make test")


def test_the_links_lead_to_files() -> None:
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", _text()):
        assert (ROOT / target).exists(), target


def test_short_without_machine_paths_or_issue_numbers() -> None:
    text = _text()
    assert len(text.splitlines()) <= 250
    assert not re.search(r"(?i)\bissues? #?\d", text)
    assert not re.search(r"/work/|/home/|/tmp/|\.\./shared", text)
