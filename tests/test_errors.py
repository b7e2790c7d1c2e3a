"""One error root: every exception class defined in ``src/fuzzypos`` (private ones included)
derives from :class:`fuzzypos.FuzzyposError`, and the public ones from ``ValueError`` or
``OSError`` as well."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from fuzzypos import FuzzyposError

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzypos"


def _exception_classes() -> list[tuple[str, str]]:
    """``(module, class)`` of every class in src whose bases name an exception: a name ending
    in Error or Exception, or one of the package's own such classes (found by importing)."""
    out = []
    for path in sorted(SRC.rglob("*.py")):
        module = ".".join(("fuzzypos", *path.relative_to(SRC).with_suffix("").parts))
        module = module.removesuffix(".__init__")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                out.append((module, node.name))
    return out


def _is_exception(module: str, name: str) -> bool:
    try:
        value = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError):  # an optional dependency, or a nested class
        return False
    return isinstance(value, type) and issubclass(value, BaseException)


CLASSES = [(m, c) for m, c in _exception_classes() if _is_exception(m, c)]


def test_the_package_has_its_exceptions() -> None:
    assert len(CLASSES) >= 20  # the scan sees them (ConfigError, LogFormatError, ...)
    assert ("fuzzypos.errors", "FuzzyposError") in CLASSES


@pytest.mark.parametrize("module,name", CLASSES, ids=lambda v: str(v))
def test_every_exception_derives_from_the_root(module: str, name: str) -> None:
    cls = getattr(importlib.import_module(module), name)
    assert issubclass(cls, FuzzyposError), f"{module}.{name}"
    if not name.startswith("_") and cls is not FuzzyposError:
        assert issubclass(cls, (ValueError, OSError)), f"{module}.{name}"


def test_one_except_catches_a_bad_log_and_a_bad_config(tmp_path: Path) -> None:
    from fuzzypos.config import Config
    from fuzzypos.io import open_log

    bad = tmp_path / "bad.clf"
    bad.write_text("FLASER 3 1 2\n")
    with pytest.raises(FuzzyposError, match=r"bad\.clf:1"):
        list(open_log(bad).records())
    toml = tmp_path / "c.toml"
    toml.write_text("[gate]\nnope = 1\n")
    with pytest.raises(FuzzyposError, match=r"gate\.nope"):
        Config.from_toml(toml)
