"""Many calls of one function as Ray tasks with one thread each, or one after the other here.

:func:`run_tasks` is what ``fuzzypos batch``, ``fuzzypos benchmark --jobs`` and the
benchmarks that run many logs share: each call a Ray task with one CPU and one thread
(:data:`ONE_THREAD_ENV`) on a local Ray (or the cluster of ``address`` / ``RAY_ADDRESS``),
or, with ``ray=False``, in this process one after the other, with the same outcomes in the
same order. Ray is the ``ray`` extra; :func:`require_ray` raises :class:`RayMissingError`
without it, :func:`ray_installed` tells whether it is there.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import FuzzyposError

__all__ = [
    "ONE_THREAD_ENV",
    "RayMissingError",
    "TaskDone",
    "quiet_ray_logging",
    "ray_installed",
    "require_ray",
    "run_tasks",
    "start_ray",
]

#: the environment of every task: one thread
ONE_THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}

_INSTALL = "pip install 'fuzzypos[ray]' (or pip install 'ray>=2.9')"


class RayMissingError(FuzzyposError, OSError):
    """Ray (the ``ray`` extra) is not installed: the message says how to install it."""

    def __init__(self, message: str = f"this needs Ray: {_INSTALL}") -> None:
        super().__init__(message)


def require_ray(what: str = "this") -> Any:
    """The ``ray`` module; :class:`RayMissingError` ("``what`` needs Ray: pip install …")
    when it is not installed."""
    try:
        import ray
    except ImportError:
        raise RayMissingError(f"{what} needs Ray: {_INSTALL}") from None
    return ray


def ray_installed() -> bool:
    """Whether ``import ray`` works."""
    try:
        require_ray()
    except RayMissingError:
        return False
    return True


class _QuietRay(logging.Filter):
    """Drops Ray's records below ERROR (its start-up INFO lines, the token-authentication
    WARNING printed at every start) from the handlers it is put on."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.ERROR


_QUIET = _QuietRay()


def quiet_ray_logging(quiet: bool = True) -> None:
    """Ray's own log lines on this process's stderr below ERROR dropped (``quiet``), or let
    through again: on the ``ray`` logger and its handlers, which Ray sets up on import."""
    logger = logging.getLogger("ray")
    for target in (logger, *logger.handlers):
        if quiet:
            target.addFilter(_QUIET)
        else:
            target.removeFilter(_QUIET)


def start_ray(ray: Any, address: str | None, jobs: int, verbose: bool = False) -> bool:
    """Join ``address`` (or ``RAY_ADDRESS``), else start a local Ray with ``jobs`` CPUs; True
    when started here (and to be shut down); nothing when Ray is already up in this process.
    Unless ``verbose``, Ray's own logging stays quiet: its lines below ERROR dropped
    (:func:`quiet_ray_logging`) and the workers' output not forwarded here."""
    if ray.is_initialized():
        return False
    quiet_ray_logging(not verbose)
    quiet: dict[str, Any] = {}
    if not verbose:
        quiet = {"logging_level": logging.ERROR, "log_to_driver": False}
    address = address or os.environ.get("RAY_ADDRESS") or None
    if address:
        ray.init(address=address, **quiet)
    else:
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        ray.init(address="local", num_cpus=jobs, include_dashboard=False, **quiet)
    return True


@dataclass(frozen=True)
class TaskDone:
    """One call's outcome: its index in the calls, its value, or the exception it raised
    (for a Ray task, Ray's error wrapping it, or a crashed worker's)."""

    index: int
    value: Any = None
    error: Exception | None = None

    def result(self) -> Any:
        """The value, or the call's exception raised here."""
        if self.error is not None:
            raise self.error
        return self.value


#: ``on_done(outcome)`` as each call finishes (in the order they finish)
TaskCallback = Callable[[TaskDone], None]


def run_tasks(
    fn: Callable[..., Any],
    calls: Sequence[tuple[Any, ...]],
    *,
    ray: bool = True,
    jobs: int | None = None,
    address: str | None = None,
    on_done: TaskCallback | None = None,
    verbose: bool = False,
) -> list[TaskDone]:
    """``fn(*args)`` for every ``args`` of ``calls``; the outcomes in the order of ``calls``.

    ``ray``: each call a Ray task with one CPU and :data:`ONE_THREAD_ENV`, on the Ray already
    up in this process, else the cluster of ``address`` (or ``RAY_ADDRESS``), else a local
    Ray with ``jobs`` CPUs (default: all), shut down at the end; ``fn`` and the arguments
    must pickle. Without ``ray``, the calls run here one after the other. An exception of a
    call is its outcome's ``error`` (:meth:`TaskDone.result` raises it), the other calls go
    on; an exception of ``on_done`` (``KeyboardInterrupt`` too) cancels the calls not
    finished and propagates. ``verbose``: Ray's own log lines too (:func:`start_ray`).
    Raises :class:`RayMissingError` and ``ValueError`` (``jobs``
    below 1) before any call."""
    if jobs is not None and jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    done: list[TaskDone | None] = [None] * len(calls)

    def finish(outcome: TaskDone) -> None:
        done[outcome.index] = outcome
        if on_done is not None:
            on_done(outcome)

    if not ray:
        for k, args in enumerate(calls):
            try:
                value = fn(*args)
            except Exception as exc:  # the call's outcome, for the caller to judge
                finish(TaskDone(k, error=exc))
            else:
                finish(TaskDone(k, value))
    else:
        ray_module = require_ray()
        _on_ray(ray_module, fn, calls, jobs or os.cpu_count() or 1, address, finish, verbose)
    return [d for d in done if d is not None]


def _on_ray(
    ray: Any,
    fn: Callable[..., Any],
    calls: Sequence[tuple[Any, ...]],
    jobs: int,
    address: str | None,
    finish: TaskCallback,
    verbose: bool = False,
) -> None:
    started = start_ray(ray, address, jobs, verbose)
    try:
        task = ray.remote(num_cpus=1, runtime_env={"env_vars": ONE_THREAD_ENV})(fn)
        pending = {task.remote(*args): k for k, args in enumerate(calls)}
        try:
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1)
                k = pending.pop(ready[0])
                try:
                    value = ray.get(ready[0])
                except Exception as exc:  # the task's error, or its worker's crash
                    finish(TaskDone(k, error=exc))
                else:
                    finish(TaskDone(k, value))
        finally:
            for ref in pending:  # interrupted: stop what is still running
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
    finally:
        if started:
            ray.shutdown()
