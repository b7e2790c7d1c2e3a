"""numba's ``njit(cache=True)``, typed: a compiled kernel keeps its Python signature for mypy
(numba compiles it on its first call, for the argument types of that call)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

from numba import njit

__all__ = ["kernel"]

F = TypeVar("F", bound=Callable[..., Any])


def kernel(func: F) -> F:
    """``func`` compiled on first call, its machine code cached on disk (``__pycache__``)."""
    return cast(F, njit(cache=True)(func))
