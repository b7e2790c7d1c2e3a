import sys
from pathlib import Path

from hypothesis import settings

#: the tests mirror the source (``tests/pipeline/`` for ``fuzzypos.pipeline``, ...); a test may
#: import a helper of another folder's test module by its name (``from test_plot import ...``)
_HERE = Path(__file__).resolve().parent
_NOT_TESTS = {"oracles", "__pycache__", ".hypothesis"}
for _folder in sorted(p for p in _HERE.iterdir() if p.is_dir() and p.name not in _NOT_TESTS):
    if str(_folder) not in sys.path:
        sys.path.append(str(_folder))

settings.register_profile("ci", derandomize=True, deadline=None, max_examples=100)
settings.load_profile("ci")


def pytest_collection_finish(session) -> None:
    """Start test_warm's fresh-cache compile at once, beside the rest of the session."""
    import test_warm

    if any(test_warm._WARM_TEST in item.nodeid for item in session.items):
        from fuzzypos._kernels import compiled

        if compiled():
            test_warm.start_in_background(session.config)


def pytest_sessionfinish(session) -> None:
    import test_warm

    test_warm.stop_in_background(session.config)
