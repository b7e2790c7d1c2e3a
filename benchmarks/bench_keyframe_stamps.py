"""A keyframe log with corrupt stamps, run as a user runs it: ``fuzzypos run LOG --scan-rate HZ``.

    python benchmarks/bench_keyframe_stamps.py [--data ../shared/data] [--log intel]
        [--scans 1941] [--out docs/benchmarks/keyframe-stamps.md]

Some SLAM tools write their keyframes as a CARMEN log whose stamps repeat or go back for
almost every scan. fuzzypos refuses such a log (exit 2, naming ``--scan-rate``); with
``--scan-rate HZ`` it takes the scans as evenly spaced in file order. This benchmark makes
such a log from a shared one and times the command a user types:

1. the shared log thinned to keyframes, a scan each time the odometry has moved 0.5 m or
   turned 10° (``thinning.thin_indices``; every relation's end scans kept too, so the
   run can be scored), the first ``--scans`` of them;
2. their stamps corrupted as such tools write them (:func:`corrupt_stamps`: each stamp
   rounded down to a multiple of 10 s, and every third scan put 0.2 s before the scan before
   it), written as a CARMEN log (``thinning.write_thinned``), and the same scans with
   their own stamps beside it;
3. ``fuzzypos run`` on the corrupt log without ``--scan-rate`` (must exit 2 naming it), then
   with ``--scan-rate`` at the keyframes' mean rate (scans ÷ the span of their true stamps),
   timed from the command's start to its end (process start, reading, loading the compiled
   kernels, positioning, writing); and ``fuzzypos run`` on the log with its own stamps;
4. both trajectories scored on the log's relations whose two ends are kept scans (the
   corrupt run's stamps mapped back to the scans' own first).

The table is printed and written to ``--out`` with the date, commit, machine and command.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from fuzzypos.eval import relations_errors
from fuzzypos.io import Relations, open_log, read_relations, read_tum

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_honesty import commit, machine
from thinning import LOGS, thin_indices, write_thinned

#: keyframes: a scan kept each time the odometry has moved this far (m) or turned (degrees)
KEYFRAME_STEP = (0.5, 10.0)
#: the issue's bound on the run's wall time (seconds) for a 1,941-scan log of this kind
TARGET_SECONDS = 120.0


def corrupt_stamps(stamps: np.ndarray) -> np.ndarray:
    """Stamps as a keyframe writer spoils them: rounded down to a multiple of 10 s (repeats),
    and every third scan 0.2 s before the scan before it (going back)."""
    out = 10.0 * np.floor(np.asarray(stamps, dtype=float) / 10.0)
    out[2::3] = out[1::3][: out[2::3].shape[0]] - 0.2
    return out


def make_logs(log: Path, relations: Relations, n: int, folder: Path) -> dict[str, Any]:
    """The keyframe log with its own stamps and with corrupt ones, written into ``folder``."""
    records = list(open_log(log).records())
    stamps = np.array([r.scan.stamp for r in records])
    odometry = [None if r.odometry is None else r.odometry.as_array() for r in records]
    ends = np.concatenate([relations.t1, relations.t2])
    kept = [records[k] for k in thin_indices(stamps, odometry, ends, *KEYFRAME_STEP)][:n]
    true = np.array([r.scan.stamp for r in kept])
    bad = corrupt_stamps(true)
    spoilt = [
        r._replace(scan=dataclasses.replace(r.scan, stamp=float(t))) for r, t in zip(kept, bad)
    ]
    write_thinned(folder / "keyframes.clf", kept, log.name)
    write_thinned(folder / "keyframes-corrupt.clf", spoilt, log.name)
    back = np.diff(bad) <= 0.0
    return {
        "scans": len(kept),
        "true": true,
        "repeat_or_back": int(back.sum()),
        "rate_hz": (len(kept) - 1) / float(true[-1] - true[0]),
    }


def run(args: list[str]) -> tuple[int, float, str]:
    """``fuzzypos ARGS`` in a new process: exit code, wall seconds, stderr."""
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", "from fuzzypos.cli import app; app()", *args],
        capture_output=True, text=True, timeout=1800,
    )  # fmt: skip
    return done.returncode, time.perf_counter() - t0, done.stderr


def score(tum: Path, relations: Relations, stamps: np.ndarray | None) -> dict[str, float]:
    """``tum`` on ``relations`` (its stamps first replaced by ``stamps``, row for row)."""
    own, poses = read_tum(tum)
    at = own if stamps is None else np.asarray(stamps, dtype=float)
    return relations_errors(at, poses, relations).as_dict()


def measure(data: Path, name: str, n: int, folder: Path) -> dict[str, Any]:
    log, rel_path = (data / part for part in LOGS[name])
    relations = read_relations(rel_path)
    made = make_logs(log, relations, n, folder)
    true = made["true"]
    inside = (relations.t1 >= true[0] - 0.002) & (relations.t2 <= true[-1] + 0.002)
    relations = Relations(relations.t1[inside], relations.t2[inside], relations.motion[inside])
    corrupt = folder / "keyframes-corrupt.clf"
    refused, _, why = run(["run", str(corrupt), "--results", str(folder / "refused")])
    rate = f"{made['rate_hz']:.4g}"
    code, seconds, err = run(
        ["run", str(corrupt), "--scan-rate", rate, "--results", str(folder / "corrupt")]
    )
    if code != 0:
        raise SystemExit(f"fuzzypos run --scan-rate failed ({code}): {err.strip()}")
    own_code, own_seconds, err = run(
        ["run", str(folder / "keyframes.clf"), "--results", str(folder / "own")]
    )
    if own_code != 0:
        raise SystemExit(f"fuzzypos run on the keyframes failed ({own_code}): {err.strip()}")
    rows = read_tum(folder / "corrupt" / "trajectory.tum")[0].shape[0]
    return {
        "log": name,
        "scans": made["scans"],
        "repeat_or_back": made["repeat_or_back"],
        "refused_exit": refused,
        "refusal_names_flag": "--scan-rate" in why,
        "scan_rate_hz": rate,
        "seconds": seconds,
        "own_seconds": own_seconds,
        "rows": rows,
        "relations": int(relations.t1.shape[0]),
        "scan_rate": score(folder / "corrupt" / "trajectory.tum", relations, true),
        "own": score(folder / "own" / "trajectory.tum", relations, None),
    }


def table(r: dict[str, Any]) -> str:
    def fig(s: dict[str, float]) -> str:
        return (
            f"{s['all_trans_mean_m']:.4f} m / {s['all_rot_mean_deg']:.3f}° | "
            f"{s['local_trans_mean_m']:.4f} m / {s['local_rot_mean_deg']:.3f}°"
        )

    ok = "✓" if r["seconds"] <= TARGET_SECONDS * r["scans"] / 1941 else "✗"
    return (
        "| run | scans | exit | wall s | trajectory rows | all relations | local relations |\n"
        "|---|---:|---:|---:|---:|---|---|\n"
        f"| corrupt stamps, no flag | {r['scans']} | {r['refused_exit']} | | | | |\n"
        f"| corrupt stamps, `--scan-rate {r['scan_rate_hz']}` | {r['scans']} | 0 | "
        f"{r['seconds']:.1f} {ok} | {r['rows']} | {fig(r['scan_rate'])} |\n"
        f"| the same scans, their own stamps | {r['scans']} | 0 | {r['own_seconds']:.1f} | "
        f"| {fig(r['own'])} |\n"
    )


def markdown(r: dict[str, Any], meta: dict[str, str]) -> str:
    return (
        "# A keyframe log with corrupt stamps, with `--scan-rate`\n\n"
        f"- date: {meta['date']}\n- commit: {meta['commit']}\n- machine: {meta['machine']}\n"
        f"- command: `{meta['command']}`\n\n"
        f"{r['log']} thinned to a scan every {KEYFRAME_STEP[0]} m or {KEYFRAME_STEP[1]:g}° of "
        f"odometry (and every relation's ends), the first {r['scans']} scans; their stamps "
        f"corrupted as keyframe writers do ({r['repeat_or_back']} of them repeat or go back). "
        "Without the flag the run is refused"
        + (" naming `--scan-rate`" if r["refusal_names_flag"] else " (the flag NOT named)")
        + f"; with it the command's wall time (process start to end; ✓: under "
        f"{TARGET_SECONDS:.0f} s for 1,941 scans, scaled to the scans here) and the scores on "
        f"the {r['relations']} relations whose ends are kept scans (mean translation / "
        "rotation), against the same scans run with their own stamps. "
        "`benchmarks/bench_keyframe_stamps.py`'s docstring has the details.\n\n" + table(r)
    )


def main(argv: list[str] | None = None) -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=here.parent.parent / "shared" / "data")
    ap.add_argument("--log", default="intel", choices=sorted(LOGS))
    ap.add_argument("--scans", type=int, default=1941)
    ap.add_argument("--out", type=Path, default=here.parent / "docs/benchmarks/keyframe-stamps.md")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        r = measure(a.data, a.log, a.scans, Path(tmp))
    meta = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": commit(),
        "machine": machine(),
        "command": (
            "python benchmarks/bench_keyframe_stamps.py "
            + shlex.join(argv if argv is not None else sys.argv[1:])
        ).strip(),
    }
    text = markdown(r, meta)
    print(text)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(text, encoding="utf-8")
    if not (r["refused_exit"] == 2 and r["refusal_names_flag"] and r["rows"] == r["scans"]):
        raise SystemExit(1)
    if not math.isfinite(r["seconds"]):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
