"""Small defects of the command line (issue 35): ``run --relations`` prints the score without
``--loop-closure``; ``fuzzypos --version``; help text keeps its ``[...]`` (rich took
``[graph]`` in ``pip install 'fuzzypos[graph]'`` for markup and dropped it)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import typing

import numpy as np
import pytest
import typer
from typer.models import ParameterInfo
from typer.testing import CliRunner

from fuzzypos import __version__
from fuzzypos.cli import app
from fuzzypos.cli.help import escape_markup
from helpers import write_relations, write_sim_log

runner = CliRunner()


@pytest.fixture(scope="module")
def scored_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("small")
    path = d / "sim.clf"
    run = write_sim_log(path)
    st, truth = np.asarray(run.stamps), np.asarray(run.true_poses)
    rel = d / "sim.relations"
    write_relations(rel, st, truth, [(k, k + 3) for k in range(len(st) - 3)] + [(0, len(st) - 1)])
    return path, rel


# -- run --relations ---------------------------------------------------------------------------
def test_run_with_relations_prints_the_score_without_loop_closure(scored_log, tmp_path):
    path, rel = scored_log
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--relations", str(rel), "--results", str(out)])
    assert res.exit_code == 0, res.output
    r = json.loads((out / "summary.json").read_text())["relations"]
    line = next(ln for ln in res.output.splitlines() if ln.startswith("relations: "))
    assert line == (
        f"relations: all {r['all_trans_mean_m']:.3f} m / {r['all_rot_mean_deg']:.2f}°, "
        f"local {r['local_trans_mean_m']:.4f} m / {r['local_rot_mean_deg']:.3f}°"
    )
    assert r["all_matched"] > 0 and r["local_matched"] > 0
    # without --relations, no score
    res = runner.invoke(app, ["run", str(path), "--results", str(tmp_path / "plain")])
    assert res.exit_code == 0, res.output
    assert not [ln for ln in res.output.splitlines() if ln.startswith("relations")], res.output


# -- --version ----------------------------------------------------------------------------------
def test_version_prints_the_version():
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0, res.output
    assert res.output == f"fuzzypos {__version__}\n"


def test_version_from_the_console_entry_point():
    """``python -m fuzzypos --version``, or the ``fuzzypos`` script's ``main``."""
    code = "import sys; from fuzzypos.cli import main; sys.argv = ['fuzzypos', '--version']; main()"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"fuzzypos {__version__}"


def test_the_commands_still_run_and_no_arguments_still_show_the_help():
    res = runner.invoke(app, [])
    assert "Usage:" in res.output and "run" in res.output
    assert runner.invoke(app, ["config"]).exit_code == 0


# -- [...] in help ------------------------------------------------------------------------------
_BRACKETS = re.compile(r"\[[a-z#/@][^\[\]]*\]")


def _bracketed_help() -> dict[str, list[str]]:
    """command → the ``[...]`` that rich would take for markup in its help, as written."""
    out: dict[str, list[str]] = {}
    for command in app.registered_commands:
        assert command.callback is not None
        name = command.name or command.callback.__name__.replace("_", "-")
        texts = [command.help or command.callback.__doc__ or ""]
        for hint in typing.get_type_hints(command.callback, include_extras=True).values():
            texts += [
                info.help for info in getattr(hint, "__metadata__", ()) if
                isinstance(info, ParameterInfo) and info.help
            ]  # fmt: skip
        found = [m for t in texts for m in _BRACKETS.findall(t.replace("\\[", "["))]
        if found:
            out[name] = found
    return out


def _plain(output: str) -> str:
    """The help's words, its box drawing and line breaks gone."""
    return " ".join(re.sub(r"[│╭╮╰╯─]", " ", output).split())


def test_help_shows_every_bracket_it_has():
    bracketed = _bracketed_help()
    assert "[graph]" in bracketed["run"] and "[loop_closure]" in bracketed["run"], bracketed
    for name, found in bracketed.items():
        res = runner.invoke(app, [name, "--help"], env={"COLUMNS": "200"})
        assert res.exit_code == 0, res.output
        shown = _plain(res.output)
        for text in found:
            assert text in shown, (name, text, shown)
        assert "\\[" not in shown, (name, shown)


def test_run_help_names_the_extra_to_install():
    res = runner.invoke(app, ["run", "--help"], env={"COLUMNS": "200"})
    shown = _plain(res.output)
    assert "needs pip install 'fuzzypos[graph]'" in shown, shown
    assert "keyframes ([loop_closure], needs" in shown, shown


def test_help_texts_are_escaped_once():
    """However often a command's help is shown, each text is escaped once."""
    group = typer.main.get_command(app)
    run = group.commands["run"]  # type: ignore[attr-defined]
    escape_markup(group)
    once = [p.help for p in run.params]
    assert any("fuzzypos\\[graph]" in (h or "") for h in once), once
    escape_markup(group)
    escape_markup(run)
    assert [p.help for p in run.params] == once


def test_the_benchmark_table_keeps_every_number_at_80_columns() -> None:
    """In an 80-column terminal the benchmark's table (the wide one would cut every number to
    an ellipsis) shows each value's digits whole; a wide terminal keeps a line a row."""
    from rich.console import Console

    from fuzzypos.cli.tables import benchmark_table

    row = {
        "log": "fr-clinic", "config": "default+loop_closure online",
        "all_trans_mean_m": 3.3478, "all_trans_std_m": 5.1234, "all_rot_mean_deg": 1.5812,
        "all_rot_std_deg": 2.3456, "local_trans_mean_m": 0.0813, "local_trans_std_m": 0.1021,
        "local_trans_median_m": 0.0534, "local_rot_mean_deg": 0.6931, "local_rot_std_deg": 0.9087,
        "all_matched": 2615, "local_matched": 2489, "scans_per_second": 1234.4,
        "scans_degraded": 603, "odometry_jumps_rejected": 17,
    }  # fmt: skip
    values = ["3.348", "5.123", "1.58", "2.35", "0.081", "0.102", "0.053", "0.69", "0.91"]
    values += ["2615", "2489", "1234", "603", "17"]
    for width in (80, 200):
        table, _ = benchmark_table([row, {**row, "log": "intel", "config": "odometry"}], "t", width)
        console = Console(width=width, record=True)
        console.print(table)
        text = console.export_text()
        assert "…" not in text
        for value in values:
            assert text.count(value) >= 2, (width, value, text)
        assert max(len(line) for line in text.splitlines()) <= width
    assert "3.348±5.123" in text  # (the wide layout)


# -- the kernels compiling on first use ---------------------------------------------------------
@pytest.mark.parametrize("cold", [True, False])
def test_run_says_the_kernels_compile_only_where_the_cache_is_cold(
    scored_log, tmp_path, monkeypatch, cold
):
    from fuzzypos.cli.help import COMPILING
    from fuzzypos.pipeline import warm

    warm.compile_kernels()  # compiled in this process: the warm-up below only pretends
    calls: list[object] = []
    monkeypatch.setattr(warm, "compiled", lambda: True)
    monkeypatch.setattr(warm, "_compiled_in", {})
    monkeypatch.setattr(warm, "kernels_cold", lambda *, in_map=False: cold)
    monkeypatch.setattr(
        warm, "warm_up", lambda config=None, *, in_map=False: calls.append(config) or 0.0
    )
    path, _ = scored_log
    res = runner.invoke(app, ["run", str(path), "--results", str(tmp_path / "res")])
    assert res.exit_code == 0, res.output
    assert len(calls) == 1  # compiled before the run, once
    said = [ln for ln in res.stderr.splitlines() if ln == COMPILING]
    assert said == ([COMPILING] if cold else []), res.stderr
    assert COMPILING not in res.stdout
    summary = json.loads((tmp_path / "res" / "summary.json").read_text())
    assert summary["compile_seconds"] >= 0.0


def test_demo_says_what_it_does_before_the_kernels_compile(tmp_path, monkeypatch):
    from fuzzypos.cli.help import COMPILING
    from fuzzypos.pipeline import warm

    warm.compile_kernels()
    monkeypatch.setattr(warm, "compiled", lambda: True)
    monkeypatch.setattr(warm, "_compiled_in", {})
    monkeypatch.setattr(warm, "kernels_cold", lambda *, in_map=False: True)
    monkeypatch.setattr(warm, "warm_up", lambda config=None, *, in_map=False: 0.0)
    res = runner.invoke(app, ["demo", "--laps", "0.05", "--out", str(tmp_path / "demo")])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0].startswith("fuzzypos demo: simulating"), lines
    assert lines.index(COMPILING) > 0, lines
