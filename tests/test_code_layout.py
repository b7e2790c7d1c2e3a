"""The package's shape: packages by role, a few plain modules at the top; a module imports only
from layers below its own (or from its own package), so that ``io`` never reaches up into the
pipeline and the core never into the command line; no two modules import each other, even
through others; functions stay under 100 lines (modules are sized by concept), and
``Positioner.update`` reads as its stages."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzypos"

#: bottom up; a name is a module or a subpackage of ``fuzzypos``
LAYERS = (
    ("_version", "errors"),
    ("geometry", "config", "_kernels"),
    ("fuzzy", "scan"),
    ("features",),
    ("matching",),
    ("pipeline",),
    ("io", "sim"),
    ("eval", "graph", "plot", "localization"),
    ("jobs",),
    ("cli",),
    ("logs", "evaluation"),  # deprecated paths: re-exports of io.logs and eval.metrics
)
RANK = {name: k for k, names in enumerate(LAYERS) for name in names}
#: the plain modules at the package's top, at most (the rest are packages by role)
MAX_TOP_MODULES = 12


def _unit(path: Path) -> str:
    """The top-level unit a module belongs to: ``matching/lines.py`` → ``matching``."""
    return path.relative_to(SRC).with_suffix("").parts[0]


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
    return out


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
    assert _imports(SRC / "jobs" / "run.py", "from ..config.schema import x\n") == {"config"}


def test_the_top_holds_few_plain_modules() -> None:
    top = sorted(p.name for p in SRC.glob("*.py"))
    assert len(top) <= MAX_TOP_MODULES, top


# -- no import cycles: no module imports one that (through others) imports it ------------------
def _module_name(path: Path) -> str:
    parts = ("fuzzypos",) + path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_level_imports(name: str, source: str, modules: set[str]) -> set[str]:
    """The modules of ``fuzzypos`` that module ``name`` imports when it is imported: its
    statements at module level (also under ``if``/``try``), not those inside functions or an
    ``if TYPE_CHECKING:`` block. ``from .x import y`` is ``x`` (and ``x.y`` where that is a
    module)."""
    package = name if name in _PACKAGES else name.rsplit(".", 1)[0]
    out: set[str] = set()

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, ast.If):
                test = node.test
                if isinstance(test, ast.Name) and test.id == "TYPE_CHECKING":
                    visit(node.orelse)
                    continue
                visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                for block in (node.body, node.orelse, node.finalbody):
                    visit(block)
                for handler in node.handlers:
                    visit(handler.body)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for alias in node.names:
                    if f"{target}.{alias.name}" in modules:
                        out.add(f"{target}.{alias.name}")
                    elif target in modules:
                        out.add(target)
            elif isinstance(node, ast.Import):
                out.update(a.name for a in node.names if a.name in modules)

    visit(ast.parse(source).body)
    return out - {name}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return found


_ALL = sorted(SRC.rglob("*.py"))
_PACKAGES = {_module_name(p) for p in _ALL if p.name == "__init__.py"}


def test_no_module_imports_itself_through_others() -> None:
    modules = {_module_name(p) for p in _ALL}
    graph = {
        _module_name(p): _module_level_imports(
            _module_name(p), p.read_text(encoding="utf-8"), modules
        )
        for p in _ALL
    }
    assert not _cycles(graph), _cycles(graph)


def test_the_cycle_check_sees_a_cycle() -> None:
    modules = {"fuzzypos.sim.world", "fuzzypos.sim.worldfile", "fuzzypos.sim"}
    world = _module_level_imports(
        "fuzzypos.sim.world", "from .worldfile import read_world_file\n", modules
    )
    lazy = _module_level_imports(
        "fuzzypos.sim.world", "def f():\n    from .worldfile import read_world_file\n", modules
    )
    typing_only = _module_level_imports(
        "fuzzypos.sim.world", "if TYPE_CHECKING:\n    from .worldfile import x\n", modules
    )
    assert world == {"fuzzypos.sim.worldfile"} and not lazy and not typing_only
    graph = {"fuzzypos.sim.world": world, "fuzzypos.sim.worldfile": {"fuzzypos.sim.world"}}
    assert _cycles(graph) == [["fuzzypos.sim.world", "fuzzypos.sim.worldfile"]]


# -- the code's size: short functions ---------------------------------------------------------
MAX_FUNCTION_LINES = 100


def _functions(path: Path) -> list[tuple[str, int]]:
    """``(name, lines)`` of every function and method of a module, but typer's command
    functions in ``cli/`` (their options are declared in their signatures)."""
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
def test_functions_stay_short(path: Path) -> None:
    long = [(name, n) for name, n in _functions(path) if n > MAX_FUNCTION_LINES]
    assert not long, f"{path.name}: functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_positioner_update_reads_as_its_stages() -> None:
    lines = dict(_functions(SRC / "pipeline" / "positioner.py"))
    assert 10 < lines["update"] <= 60, lines["update"]
