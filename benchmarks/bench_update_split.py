"""Where ``Positioner.update``'s time goes: each compiled kernel's share and the Python
between them, on the same scans in one process.

    OMP_NUM_THREADS=1 python benchmarks/bench_update_split.py [--data ../shared/data]
        [--logs intel,aces,sim180,sim360] [--max-scans N] [--repeat R] [--gicp]

Each log is read once (``fuzzypos.io.logs.open_log(path).records()``) and run through a fresh
``Positioner()`` (the default) ``R`` times (default 3), alternately without and with a timer
around every compiled kernel the pipeline calls from Python (each module-level dispatcher of
``fuzzypos._kernels``; the kernels' calls of each other stay inside the compiled code). The
runs without timers give ``update``'s time per scan; the runs with them, each kernel's calls
per scan and time per call, and ``update``'s time with the timers on. "Python between the
kernels" is that time less the kernels' and less the timers' own cost (measured here on an
empty call). Medians of the R runs. ``sim180`` and ``sim360`` are ``bench_peers.py``'s
simulated logs. With ``--gicp``, small_gicp GICP's ``align`` (``bench_peers.py``'s peer, against
1 m / 30° keyframes; ``pip install -e '.[bench]'``) is timed on the same scans too, a run after
each pair of fuzzypos's, and update's, the kernels' and the Python's times are printed over
its: issue 12's proxy (update at most 0.3 times GICP's time on 180 beams) beside what the
kernels alone take. A machine shared with others moves every figure by tens of percent from
one run to the next; the shares move less.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ[_var] = "1"  # one thread, set before numpy loads

import argparse  # noqa: E402
import importlib  # noqa: E402
import pkgutil  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import fuzzypos._kernels  # noqa: E402
from fuzzypos import Positioner  # noqa: E402
from fuzzypos.io import open_log  # noqa: E402
from fuzzypos.pipeline.warm import warm_up  # noqa: E402

sys.path.insert(0, os.fspath(Path(__file__).resolve().parent))
import bench_peers  # noqa: E402
from bench_peers import LOGS, SIMULATED, simulated_log  # noqa: E402

_CLOCK = time.perf_counter


def kernels() -> dict[str, tuple[Any, str, Any]]:
    """Every compiled kernel of ``fuzzypos._kernels`` defined at a module's top level, by
    ``module.name``: (its module, its name, the dispatcher)."""
    from numba.core.registry import CPUDispatcher

    out: dict[str, tuple[Any, str, Any]] = {}
    for info in pkgutil.iter_modules(fuzzypos._kernels.__path__):
        module = importlib.import_module(f"fuzzypos._kernels.{info.name}")
        for name, value in vars(module).items():
            func = getattr(value, "py_func", None)
            if (
                isinstance(value, CPUDispatcher)
                and func is not None
                and func.__module__ == module.__name__
            ):
                out[f"{info.name}.{name}"] = (module, name, value)
    return out


@contextmanager
def timed(
    found: dict[str, tuple[Any, str, Any]], seconds: Counter, calls: Counter
) -> Iterator[None]:
    """Each kernel in ``found`` replaced, for the duration, by a call that adds its time and
    count to ``seconds`` and ``calls``."""

    def timer(label: str, dispatcher: Any) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            t0 = _CLOCK()
            try:
                return dispatcher(*args)
            finally:
                seconds[label] += _CLOCK() - t0
                calls[label] += 1

        return call

    for label, (module, name, dispatcher) in found.items():
        setattr(module, name, timer(label, dispatcher))
    try:
        yield
    finally:
        for module, name, dispatcher in found.values():
            setattr(module, name, dispatcher)


def timer_cost() -> float:
    """Seconds a timer adds to a call (the timed wrapper of an empty function, less the
    function's own call)."""
    seconds, calls = Counter(), Counter()

    def empty(*args: Any) -> None:
        return None

    holder = type("Holder", (), {"f": staticmethod(empty)})
    found = {"empty": (holder, "f", empty)}
    n = 200_000
    t0 = _CLOCK()
    for _ in range(n):
        holder.f(1, 2)
    bare = _CLOCK() - t0
    with timed(found, seconds, calls):
        t0 = _CLOCK()
        for _ in range(n):
            holder.f(1, 2)
        wrapped = _CLOCK() - t0
    return max(wrapped - bare, 0.0) / n


def run(records: list[tuple[Any, Any]]) -> float:
    """Seconds of ``update`` over the records, a fresh default positioner."""
    pos = Positioner()
    total = 0.0
    for scan, odom in records:
        t0 = _CLOCK()
        pos.update(scan, odom)
        total += _CLOCK() - t0
    return total


def run_gicp(records: list[tuple[Any, Any]]) -> float:
    """Seconds of small_gicp GICP's ``align`` over the records (``bench_peers.SmallGicp``
    against 1 m / 30° keyframes, as ``bench_peers.run_method`` runs it)."""
    method = bench_peers.SmallGicp("GICP")
    method.start(bench_peers.pose_tuple(records[0][1]) if records else None)
    for scan, odom in records:
        method.step(scan, odom)
    return method.matcher_seconds


def split(records: list[tuple[Any, Any]], repeat: int, gicp: bool = False) -> dict[str, Any]:
    """``update``'s time per scan, with the timers and without, and each kernel's calls and
    time (medians of ``repeat`` runs each); with ``gicp``, small_gicp GICP's ``align`` time too
    (:func:`run_gicp`, a run after each pair; the median)."""
    found = kernels()
    plain, with_timers, peer = [], [], []
    per_run: list[tuple[Counter, Counter]] = []
    for _ in range(repeat):
        plain.append(run(records))
        seconds, calls = Counter(), Counter()
        with timed(found, seconds, calls):
            with_timers.append(run(records))
        per_run.append((seconds, calls))
        if gicp:
            peer.append(run_gicp(records))
    labels = sorted({k for s, _ in per_run for k in s})
    kernel_rows = {
        label: (
            statistics.median(s[label] for s, _ in per_run),
            statistics.median(c[label] for _, c in per_run),
        )
        for label in labels
    }
    return {
        "update": statistics.median(plain),
        "with_timers": statistics.median(with_timers),
        "kernels": kernel_rows,
        "gicp": statistics.median(peer) if peer else None,
    }


def main() -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data",
        default=os.environ.get("FUZZYPOS_DATA", os.fspath(here.parent.parent / "shared" / "data")),
        help="the shared data folder (default: ../shared/data beside the checkout)",
    )
    ap.add_argument(
        "--logs", default="intel,aces", help="comma-separated: intel, aces, sim180, sim360"
    )
    ap.add_argument("--max-scans", type=int, default=None, help="the first N scans of each log")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each log, each way (3)")
    ap.add_argument(
        "--gicp",
        action="store_true",
        help="also time small_gicp GICP's align on the same scans and print the times over it",
    )
    args = ap.parse_args()
    names = [s.strip() for s in args.logs.split(",") if s.strip()]
    unknown = [n for n in names if n not in LOGS and n not in SIMULATED]
    if unknown:
        known = ", ".join([*LOGS, *SIMULATED])
        sys.exit(f"--logs: unknown log(s) {', '.join(unknown)} (known: {known})")
    if args.repeat < 1:
        sys.exit("--repeat: at least 1")
    if args.gicp and bench_peers.small_gicp is None:
        sys.exit(f"--gicp: small_gicp is not installed ({bench_peers.INSTALL_HINT})")
    print(f"every compiled kernel ready in {warm_up():.2f} s", file=sys.stderr)
    cost = timer_cost()
    scratch = tempfile.TemporaryDirectory(prefix="bench_split_")
    for name in names:
        if name in SIMULATED:
            path, _ = simulated_log(Path(scratch.name), name)
        else:
            path = Path(args.data) / LOGS[name]
        if not path.exists():
            sys.exit(f"{path}: missing; see --data")
        records = [(r.scan, r.odometry) for r in open_log(path).records()]
        records = records[: args.max_scans] if args.max_scans else records
        n = len(records)
        out = split(records, args.repeat, args.gicp)
        rows = sorted(out["kernels"].items(), key=lambda kv: -kv[1][0])
        in_kernels = sum(s for s, _ in out["kernels"].values())
        n_calls = sum(c for _, c in out["kernels"].values())
        python = out["with_timers"] - in_kernels - cost * n_calls
        us = 1e6 / n
        print(
            f"\n### {path.name}: {n:,} scans, Positioner.update {out['update'] * us:.1f} µs a scan"
        )
        print(
            f"(with the timers {out['with_timers'] * us:.1f} µs; "
            f"a timer adds {cost * 1e6:.2f} µs a call)\n"
        )
        print("| part | calls a scan | µs a call | µs a scan | share of update |")
        print("|---|---:|---:|---:|---:|")
        for label, (seconds, calls) in rows:
            if seconds * us < 0.05:
                continue
            print(
                f"| kernel {label} | {calls / n:.2f} | {seconds / calls * 1e6:.1f} | "
                f"{seconds * us:.1f} | {seconds / out['with_timers']:.0%} |"
            )
        print(
            f"| all the kernels | {n_calls / n:.2f} | | {in_kernels * us:.1f} | "
            f"{in_kernels / out['with_timers']:.0%} |"
        )
        print(
            f"| Python between the kernels | | | {python * us:.1f} | "
            f"{python / out['with_timers']:.0%} |"
        )
        if out["gicp"] is not None:
            print_over_gicp(out["update"], in_kernels, python, out["gicp"], us)
    scratch.cleanup()


def print_over_gicp(
    update: float, in_kernels: float, python: float, gicp: float, us: float
) -> None:
    """The times over small_gicp GICP's ``align`` on the same scans (seconds; ``us``: µs a scan
    per second of the run)."""
    print("\n| on the same scans | µs a scan | ÷ small_gicp GICP's align |")
    print("|---|---:|---:|")
    print(f"| Positioner.update | {update * us:.1f} | {update / gicp:.2f} |")
    print(f"| all the kernels | {in_kernels * us:.1f} | {in_kernels / gicp:.2f} |")
    print(f"| Python between the kernels | {python * us:.1f} | {python / gicp:.2f} |")
    print(f"| small_gicp GICP, 1 m / 30° keyframes: align | {gicp * us:.1f} | 1.00 |")


if __name__ == "__main__":
    main()
