"""A scan's cost against its beams (issue 35, item 3): ``Positioner.update``'s time per scan on
simulated scanners of 180 to 10,000 beams, and the ratio of 10,000 beams' to 1,000's.

    OMP_NUM_THREADS=1 python benchmarks/bench_beams.py [--beams 180,1000,1081,3000,10000]
        [--scans N] [--repeat R] [--world office] [--out docs/benchmarks/beams.md]

Each scanner is the demo's (a SICK LMS200 in its 30 m mode over 180°, σ = 1 cm + 1 mm per
metre) with the number of beams changed, on the demo's circle in the world (``--world``, a
``fuzzypos.sim`` world: office by default, gym, furnished_room, rectangular_room), the demo's
slip, seed 0. The first ``--scans`` scans (default 60) run through a fresh ``Positioner()``
(the default) ``R`` times (default 3) after a warm-up; a scan's time is its ``update`` call's,
the figure the median over the scans after the first five of each run (the keyframe's first
scans), the least of the R medians. A per-scan cost that grows with the beams alone puts 10,000
beams at about ten times 1,000's (the target: at most 12); a quadratic step, at a hundred. The
table is printed and written, with the date, the commit, the machine and the command, to
``--out``. A machine shared with others moves each figure by tens of percent.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ[_var] = "1"  # one thread, set before numpy loads

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from datetime import datetime  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from fuzzypos import Positioner, sim  # noqa: E402
from fuzzypos.jobs import DemoSettings  # noqa: E402

sys.path.insert(0, os.fspath(Path(__file__).resolve().parent))
from bench_honesty import commit, machine  # noqa: E402

#: the beam counts of the table by default
BEAMS = (180, 1000, 1081, 3000, 10000)
#: the ratio reported: the last over the first
RATIO = (10000, 1000)
#: scans left out of each run's median (the first keyframe's)
SETTLE = 5


def simulated(beams: int, scans: int, world: str) -> list[tuple[Any, Any]]:
    """The first ``scans`` (scan, odometry) of the demo's run with ``beams`` beams."""
    settings = DemoSettings()
    scanner = dataclasses.replace(settings.scanner, n_beams=beams)
    laps = 1.2 * scans / settings.scanner.rate_hz * settings.speed / (2 * math.pi * settings.radius)
    path = sim.CommandedPath.circle(settings.radius, laps, settings.speed)
    run = sim.simulate_run(sim.world_by_name(world), path, scanner, settings.slip, 0)
    return [(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)][:scans]


def ms_per_scan(data: list[tuple[Any, Any]], repeat: int) -> float:
    """The least over ``repeat`` runs of the median ``update`` time (ms) after SETTLE scans."""
    medians = []
    for _ in range(repeat):
        positioner = Positioner()
        times = []
        for scan, odom in data:
            t0 = time.perf_counter()
            positioner.update(scan, odom)
            times.append(time.perf_counter() - t0)
        medians.append(1e3 * statistics.median(times[SETTLE:] or times))
    return min(medians)


def measure(beams: list[int], scans: int, repeat: int, world: str) -> dict[int, float]:
    """Each beam count's ms per scan (after a warm-up run of the smallest)."""
    ms_per_scan(simulated(min(beams), SETTLE + 2, world), 1)  # the kernels loaded
    out = {}
    for n in beams:
        out[n] = ms_per_scan(simulated(n, scans, world), repeat)
        print(f"{n} beams: {out[n]:.2f} ms a scan", flush=True)
    return out


def markdown(result: dict[int, float], meta: dict[str, str]) -> str:
    big, small = RATIO
    lines = [
        "# A scan's cost against its beams (issue 35, item 3)",
        "",
        f"- date: {meta['date']}",
        f"- commit: {meta['commit']}",
        f"- machine: {meta['machine']}",
        f"- command: `{meta['command']}`",
        "",
        (
            f"`Positioner().update` on the demo's simulated scanner with the beams changed, in "
            f"the {meta['world']} world ({meta['scans']} scans, the median after the first "
            f"{SETTLE}, the least of {meta['repeat']} runs). `benchmarks/bench_beams.py`'s "
            "docstring has the details."
        ),
        "",
        "| beams | ms per scan | ms per 1,000 beams |",
        "|---:|---:|---:|",
    ]
    lines += [f"| {n} | {ms:.2f} | {1e3 * ms / n:.3f} |" for n, ms in result.items()]
    if big in result and small in result:
        ratio = result[big] / result[small]
        lines += ["", f"{big} beams ÷ {small}: {ratio:.1f} (target: at most 12)"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beams", default=",".join(str(b) for b in BEAMS))
    parser.add_argument("--scans", type=int, default=60)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--world", default="office")
    parser.add_argument("--out", type=Path, default=Path("docs/benchmarks/beams.md"))
    args = parser.parse_args(argv)
    beams = [int(b) for b in args.beams.split(",")]
    result = measure(beams, args.scans, args.repeat, args.world)
    given = sys.argv[1:] if argv is None else argv
    meta = {
        "date": datetime.now().isoformat(timespec="seconds"),
        "commit": commit(),
        "machine": machine(),
        "command": " ".join(["python benchmarks/bench_beams.py", *given]),
        "world": args.world,
        "scans": str(args.scans),
        "repeat": str(args.repeat),
    }
    text = markdown(result, meta)
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
