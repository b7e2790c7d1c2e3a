"""The package's shape: a module imports only from layers below its own (or from its own
subpackage), so that ``io`` never reaches up into the pipeline and the core never into the
command line; functions stay under 100 lines, modules under 900, and ``Positioner.update``
reads as its stages."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzypos"

#: bottom up; a name is a module or a subpackage of ``fuzzypos``
LAYERS = (
    ("_version", "errors"),
    ("config", "geometry", "_kernels"),
    ("fuzzy", "scan"),
    ("segmentation",),
    ("features",),
    ("matching",),
    ("pipeline",),
    ("io", "sim"),
    ("evaluation", "plot", "graph", "no_returns", "odometry_check"),
    ("logs", "provenance", "folders", "tasks"),
    ("scoring", "run"),
    ("benchmark", "batch", "demo"),
    ("results",),
    ("cli",),
)
RANK = {name: k for k, names in enumerate(LAYERS) for name in names}


#: private modules that are part of another unit
PART_OF = {p.stem: "config" for p in SRC.glob("_config_*.py")}
PART_OF.update({p.stem: "cli" for p in SRC.glob("_cli_*.py")})
PART_OF.update({p.stem: "features" for p in SRC.glob("_features_*.py")})
PART_OF.update({p.stem: "run" for p in SRC.glob("_run_*.py")})


def _unit(path: Path) -> str:
    """The top-level unit a module belongs to: ``matching/lines.py`` → ``matching``."""
    name = path.relative_to(SRC).with_suffix("").parts[0]
    return PART_OF.get(name, name)


def _imports(path: Path, text: str | None = None) -> set[str]:
    """The top-level units of ``fuzzypos`` that a module (``text``, else the file's) imports,
    relative and absolute."""
    rel = path.relative_to(SRC)
    package = list(rel.parts[:-1])
    out: set[str] = set()
    source = path.read_text(encoding="utf-8") if text is None else text
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package[: len(package) - (node.level - 1)]
            parts = base + (node.module.split(".") if node.module else [])
            if parts:
                out.add(parts[0])
            else:  # ``from . import sim``: the names are the units
                out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("fuzzypos"):
            parts = (node.module or "").split(".")[1:]
            out.update([parts[0]] if parts else [a.name for a in node.names])
        elif isinstance(node, ast.Import):
            out.update(a.name.split(".")[1] for a in node.names if a.name.startswith("fuzzypos."))
    return {PART_OF.get(name, name) for name in out}


MODULES = sorted(p for p in SRC.rglob("*.py") if p.name != "__init__.py" or p.parent != SRC)


def test_every_module_has_a_layer() -> None:
    assert len(MODULES) > 30
    missing = sorted({_unit(p) for p in MODULES} - set(RANK))
    assert not missing, f"modules without a layer in LAYERS: {missing}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(SRC)))
def test_a_module_imports_only_from_layers_below(path: Path) -> None:
    unit = _unit(path)
    upward = sorted(name for name in _imports(path) - {unit} if RANK.get(name, -1) >= RANK[unit])
    assert not upward, f"{path.relative_to(SRC)} ({unit}) imports {upward} from its layer or above"


def test_the_check_sees_an_upward_import() -> None:
    """The parser finds relative, absolute and ``from . import`` imports."""
    text = "from ..pipeline import Positioner\nimport fuzzypos.cli\nfrom .. import plot\n"
    assert _imports(SRC / "io" / "fake.py", text) == {"pipeline", "cli", "plot"}
    assert _imports(SRC / "run.py", "from ._config_schema import x\n") == {"config"}


# -- the code's size: short functions, modules a reader can hold -------------------------------
MAX_FUNCTION_LINES = 100
MAX_MODULE_LINES = 900


def _functions(path: Path) -> list[tuple[str, int]]:
    """``(name, lines)`` of every function and method of a module, but typer's command
    functions in ``cli.py`` (their options are declared in their signatures)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            command = any(
                isinstance(d, ast.Call) and getattr(d.func, "attr", "") == "command"
                for d in node.decorator_list
            )
            if not command:
                out.append((node.name, (node.end_lineno or node.lineno) - node.lineno + 1))
    return out


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(SRC)))
def test_functions_and_modules_stay_short(path: Path) -> None:
    n_lines = len(path.read_text(encoding="utf-8").splitlines())
    assert n_lines <= MAX_MODULE_LINES, f"{path.name} has {n_lines} lines"
    long = [(name, n) for name, n in _functions(path) if n > MAX_FUNCTION_LINES]
    assert not long, f"{path.name}: functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_positioner_update_reads_as_its_stages() -> None:
    lines = dict(_functions(SRC / "pipeline" / "positioner.py"))
    assert 10 < lines["update"] <= 60, lines["update"]
