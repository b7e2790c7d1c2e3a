"""The numpy references of the compiled kernels (``fuzzypos._kernels``), one module per
package of ``src/fuzzypos``: the code each kernel replaced, kept here as the tests' oracles
(the property tests check kernel against reference). :func:`references` puts them in place
of the kernels' callers for the duration, for a whole chain's comparison."""

from __future__ import annotations

import contextlib
import importlib
import sys
from collections.abc import Iterator
from typing import Any


def _declines(*_args: Any, **_kwargs: Any) -> None:
    """A fused compiled call's stand-in: it declines, so the staged chain runs."""
    return None


def _stand_ins() -> list[tuple[str, str, Any]]:
    """(module, attribute, its reference): a kernel's caller and the numpy it replaced."""
    from oracles import features, fuzzy, io, matching, pipeline

    return [
        *features.STAND_INS,
        *fuzzy.STAND_INS,
        *io.STAND_INS,
        *matching.STAND_INS,
        *pipeline.STAND_INS,
    ]


def _patch(m: Any, original: object, replacement: object) -> None:
    """``replacement`` wherever a ``fuzzypos`` module (or class) holds ``original``."""
    for name, module in list(sys.modules.items()):
        if not name.startswith("fuzzypos") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if value is original:
                m.setattr(module, attr, replacement)


@contextlib.contextmanager
def references() -> Iterator[None]:
    """The numpy references in place of the compiled kernels' callers, for the duration."""
    import pytest

    with pytest.MonkeyPatch.context() as m:
        for module_name, attr, reference in _stand_ins():
            owner: Any = importlib.import_module(module_name)
            *outer, last = attr.split(".")
            for part in outer:
                owner = getattr(owner, part)
            original = vars(owner)[last]
            if callable(reference) and getattr(reference, "__module__", "").startswith("oracles"):
                # as the oracle's module holds it now (a test may wrap it there)
                reference = getattr(sys.modules[reference.__module__], reference.__name__)
            m.setattr(owner, last, reference)
            if not outer and callable(original):
                _patch(m, original, reference)
        yield


__all__ = ["_declines", "references"]
