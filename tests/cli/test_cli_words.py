"""The command line's words (issue 11, items 12 and 15): errors name the flags, not the
library's argument names; an unreadable file is the one-line error, not typer's box; help
shows no ``<bool>`` on flags and names arguments ``LOG``, not ``{log}``; ``plot-scan`` reads
a log with the reader options ``run`` and ``info`` have, into ``plots/<log>-scan<N>/`` (the
log's name without its compression suffix, as ``run`` names its results folder)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import typing
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.jobs.folders import log_name
from helpers import make_bag, standard, write_sim_log

runner = CliRunner()
COMMANDS = (
    "demo",
    "simulate",
    "config",
    "plot-scan",
    "info",
    "run",
    "localize",
    "evaluate",
    "benchmark",
)


def one_line_error(args: list[str]) -> str:
    res = runner.invoke(app, args)
    assert res.exit_code == 2, (args, res.output)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("fuzzypos: error: "), (args, res.output)
    return lines[0]


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("words") / "sim.clf.gz"
    write_sim_log(path, laps=0.05)
    return path


# -- messages speak the flags ----------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "expect", "library_word"),
    [
        (["--max-scans", "0"], "--max-scans must be at least 1, got 0", "max_scans"),
        (["--fov", "0"], "--fov must be in (0, 360]", "field_of_view_deg"),
        (["--start", "5", "--end", "3"], "--end (3 s) must not come before --start (5 s)", ""),
        (["--convention", "x"], "--convention must be one of", ""),
        (["--max-range", "-1"], "--max-range must be > 0", "max_range"),
    ],
)
def test_run_errors_name_the_flag(sim_log, tmp_path, args, expect, library_word) -> None:
    line = one_line_error(["run", str(sim_log), "--results", str(tmp_path / "r"), *args])
    assert expect in line
    if library_word:
        assert library_word not in line


def test_bag_topic_errors_name_the_flag(tmp_path) -> None:
    bag = make_bag(tmp_path, "ros1", lambda b: standard(b, scan_topics=("/a", "/b")))
    line = one_line_error(["run", str(bag), "--results", str(tmp_path / "r")])
    assert "pass --scan-topic to pick one" in line and "scan_topic" not in line
    line = one_line_error(["info", str(bag), "--scan-topic", "/nope"])
    assert f"{bag}: --scan-topic '/nope': no such topic" in line and "scan_topic" not in line


# -- an unreadable file ----------------------------------------------------------------------
def _unreadable_cases(d: Path) -> list[tuple[list[str], Path]]:
    log, toml = d / "log.clf", d / "cfg.toml"
    log.write_text("# a log\n")
    toml.write_text("[fuzzy]\n")
    for p in (log, toml):
        p.chmod(0)
    return [
        (["info", str(log)], log),
        (["run", str(log), "--results", str(d / "r")], log),
        (["plot-scan", str(log), "-n", "0", "--out", str(d / "p")], log),
        (["config", "--config", str(toml)], toml),
        (["evaluate", str(log), "--reference", str(log)], log),
    ]


def _check_unreadable(args: list[str], path: Path, code: int, out: str) -> None:
    lines = [ln for ln in out.splitlines() if ln.strip() and "atplotlib" not in ln]
    assert code == 2, (args, out)
    assert len(lines) == 1 and lines[0].startswith(f"fuzzypos: error: {path}"), (args, out)
    assert "Permission denied" in lines[0] and "Usage" not in out, (args, out)


def test_an_unreadable_file_is_the_one_line_error(tmp_path) -> None:
    """As root every file is readable, so the commands run as ``nobody`` (with setpriv)."""
    if os.geteuid() != 0:
        for args, path in _unreadable_cases(tmp_path):
            res = runner.invoke(app, args)
            _check_unreadable(args, path, res.exit_code, res.output)
        return
    if shutil.which("setpriv") is None:
        pytest.skip("running as root without setpriv: cannot make a file unreadable")
    d = Path(tempfile.mkdtemp(prefix="fuzzypos-words-"))  # /tmp: nobody may enter it
    try:
        d.chmod(0o777)
        drop = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
        probe = subprocess.run(
            [*drop, sys.executable, "-c", "import fuzzypos"], capture_output=True, timeout=120
        )
        if probe.returncode != 0:  # e.g. a checkout under a folder only root may enter
            pytest.skip("user nobody cannot import fuzzypos from this checkout")
        main = "import sys; from fuzzypos.cli import app; sys.argv[0] = 'fuzzypos'; app()"
        env = {**os.environ, "HOME": str(d), "MPLCONFIGDIR": str(d / "mpl")}
        for args, path in _unreadable_cases(d):
            res = subprocess.run(
                [*drop, sys.executable, "-c", main, *args],
                capture_output=True,
                text=True,
                env=env,
                timeout=120,
            )
            _check_unreadable(args, path, res.returncode, res.stdout + res.stderr)
    finally:
        shutil.rmtree(d)


def test_no_path_parameter_is_checked_by_typer_for_readability() -> None:
    """Typer's check answers with its boxed usage error; the reader's own is one line."""
    paths, checked = [], []
    for command in app.registered_commands:
        assert command.callback is not None
        hints = typing.get_type_hints(command.callback, include_extras=True)
        for name, hint in hints.items():
            if typing.get_origin(hint) is not typing.Annotated:
                continue
            base, info = typing.get_args(hint)[:2]
            if base is Path or Path in typing.get_args(base):
                paths.append(name)
                if info.readable:
                    checked.append(f"{command.callback.__name__} {name}")
    assert len(paths) >= 10 and not checked, checked


# -- help ------------------------------------------------------------------------------------
@pytest.mark.parametrize("command", COMMANDS)
def test_help_has_no_bool_metavars_nor_braces(command: str) -> None:
    res = runner.invoke(app, [command, "--help"], env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    assert "<bool>" not in res.output and "``" not in res.output
    usage = next(ln for ln in res.output.splitlines() if "Usage:" in ln)
    assert "{" not in usage and "}" not in usage, usage
    assert usage.split("Usage:")[1].split()[1:3] == [command, "[OPTIONS]"], usage
    if command in ("plot-scan", "info", "run"):
        assert usage.split()[-1] == "LOG", usage


def test_the_main_help_has_no_bool_metavar() -> None:
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0 and "--help" in res.output and "<bool>" not in res.output


def test_info_help_names_the_scanner_section() -> None:
    res = runner.invoke(app, ["info", "--help"], env={"COLUMNS": "200"})
    assert "band of the configuration's scanner section" in " ".join(res.output.split())


# -- plot-scan reads logs as run and info do ---------------------------------------------------
READER_OPTIONS = ("--scan-topic", "--skip-bad-lines", "--fov", "--convention")


def _options(command: str) -> dict[str, object]:
    group = typer.main.get_command(app)
    cmd = group.commands[command]  # type: ignore[attr-defined]
    return {o: p for p in cmd.params for o in p.opts if o.startswith("--")}


@pytest.mark.parametrize("flag", READER_OPTIONS)
def test_plot_scan_has_the_reader_options_of_run_and_info(flag: str) -> None:
    plot, run, info = _options("plot-scan"), _options("run"), _options("info")
    assert flag in plot, sorted(plot)
    for other in (run, info):
        assert plot[flag].help == other[flag].help  # type: ignore[attr-defined]
        assert plot[flag].default == other[flag].default  # type: ignore[attr-defined]


def test_plot_scan_picks_a_bag_topic(tmp_path) -> None:
    bag = make_bag(tmp_path, "ros1", lambda b: standard(b, scan_topics=("/a", "/b")))
    out = tmp_path / "figs"
    assert "--scan-topic" in one_line_error(["plot-scan", str(bag), "-n", "1", "--out", str(out)])
    res = runner.invoke(
        app, ["plot-scan", str(bag), "-n", "1", "--scan-topic", "/b", "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert len(list(out.glob("fig1[3-8]_*.png"))) == 6


def test_plot_scan_skips_bad_lines_when_asked(sim_log, tmp_path) -> None:
    import gzip

    bad = tmp_path / "bad.clf"
    bad.write_text("FLASER 3 1.0 oops\n" + gzip.decompress(sim_log.read_bytes()).decode())
    out = tmp_path / "figs"
    assert f"{bad}:1" in one_line_error(["plot-scan", str(bad), "-n", "0", "--out", str(out)])
    args = ["plot-scan", str(bad), "-n", "0", "--out", str(out), "--skip-bad-lines"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output


def test_plot_scan_field_of_view_is_used(sim_log, tmp_path) -> None:
    line = one_line_error(["plot-scan", str(sim_log), "-n", "0", "--fov", "400"])
    assert "--fov must be in (0, 360]" in line


def test_plot_scan_default_folder_drops_the_log_suffixes(sim_log, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["plot-scan", str(sim_log), "-n", "2"])
    assert res.exit_code == 0, res.output
    # named as run names its results folder: the log without its compression suffix
    assert log_name(sim_log, keep_format=True) == "sim.clf"
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == ["sim.clf-scan2"]
    assert len(list((tmp_path / "plots" / "sim.clf-scan2").glob("fig1[3-8]_*.png"))) == 6
