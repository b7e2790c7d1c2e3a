"""docs/configuration.md is generated from the settings' declarations and must not drift: it is
exactly what ``fuzzypos config --markdown`` prints (regenerate it with
``fuzzypos config --markdown > docs/configuration.md``)."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from fuzzypos import Config
from fuzzypos.cli import app
from fuzzypos.config.docs import settings_lines, settings_markdown

DOC = Path(__file__).resolve().parents[2] / "docs" / "configuration.md"


def test_the_committed_configuration_reference_is_the_generators_output() -> None:
    assert DOC.read_text(encoding="utf-8") == settings_markdown(), (
        "docs/configuration.md differs from the config schema: run "
        "`fuzzypos config --markdown > docs/configuration.md`"
    )


def test_the_reference_names_every_setting_with_its_reason() -> None:
    sections = {part.split("]`", 1)[0]: part for part in settings_markdown().split("\n## `[")[1:]}
    for key, spec in Config.schema().items():
        section, name = key.split(".")
        toml_key = name + "_deg" if spec.is_angle else name
        lines = sections[section].splitlines()
        row = next(r for r in lines if r.startswith(f"| `{toml_key}` |"))
        assert " ".join(spec.reason.split()).replace("|", "\\|") in row


def test_the_paper_column_shows_what_the_preset_changes() -> None:
    row = next(r for r in settings_markdown().splitlines() if r.startswith("| `match_lines` |"))
    assert row.split(" | ")[1:3] == ["`true`", "`false`"]


def test_the_cli_prints_the_reference_and_the_reasons() -> None:
    runner = CliRunner()
    out = runner.invoke(app, ["config", "--markdown"])
    assert out.exit_code == 0, out.output
    assert out.output == settings_markdown()
    out = runner.invoke(app, ["config", "--reasons"])
    assert out.exit_code == 0, out.output
    assert out.output.splitlines() == settings_lines()
    assert len(settings_lines()) == len(Config.schema())
