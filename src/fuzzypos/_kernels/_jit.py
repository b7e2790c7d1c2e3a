"""numba's ``njit(cache=True)``, typed: a compiled kernel keeps its Python signature for mypy
(numba compiles it on its first call, for the argument types of that call).

numba keys a kernel's disk cache on its own module's source alone, while the machine code it
caches holds the kernels it calls from other modules too: after one of those changed, it
would load their old code (numba/numba#1833; a kernel module edited in a checkout, not a
release, whose install rewrites every file). The cache here is keyed on every kernel
module's source as well (:func:`sources_stamp`)."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any, TypeVar, cast

from numba import njit

__all__ = ["contracted", "kernel", "inlined", "sources_stamp"]

F = TypeVar("F", bound=Callable[..., Any])
_HERE = Path(__file__).resolve().parent


@cache
def sources_stamp(folder: Path = _HERE) -> str:
    """The SHA-256 of every module's source in ``folder`` (the kernels'), by name."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.py")):
        digest.update(path.name.encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()


def _stamped(dispatcher: Any) -> Any:
    """``dispatcher``'s cache index keyed on :func:`sources_stamp` beside numba's own stamp of
    its module (numba's ``IndexDataCacheFile``, whose index is stale where its stamp is not
    the one it was saved with; ``tests/pipeline/test_warm.py`` checks that the installed numba has
    it)."""
    index = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if index is not None and hasattr(index, "_source_stamp"):
        index._source_stamp = (index._source_stamp, sources_stamp())
    return dispatcher


def kernel(func: F) -> F:
    """``func`` compiled on first call, its machine code cached on disk (``__pycache__``)."""
    return cast(F, _stamped(njit(cache=True)(func)))


def inlined(func: F) -> F:
    """A :func:`kernel` that numba compiles into each kernel that calls it (``inline="always"``):
    a call that passes arrays counts their references, which costs more than a grid query's
    scan."""
    return cast(F, _stamped(njit(cache=True, inline="always")(func)))


def contracted(func: F) -> F:
    """A :func:`kernel` whose ``a * b + c`` are fused multiply-adds (``fastmath={"contract"}``),
    as numpy's matrix product computes them (each entry's sum a chain of fused multiply-adds
    from 0.0): for arithmetic that must give numpy's values to the bit."""
    return cast(F, _stamped(njit(cache=True, fastmath={"contract"})(func)))
