"""Are the front end's covariances honest over short stretches? Its step covariances composed
along the benchmark's short relations, and the relations' errors measured against them
(issue 34, item 2).

    python benchmarks/bench_honesty.py RESULTS RELATIONS [RESULTS RELATIONS ...]
    python benchmarks/bench_honesty.py --runs DIR [--data ../shared/data] [--logs ...]
    python benchmarks/bench_honesty.py --run [--runs DIR] [--data ../shared/data] [--logs ...]

A run is a ``fuzzypos run`` results folder: ``trajectory.tum`` (one pose per scan, in file
order) and ``covariance.csv`` (per scan, the covariance of its step from the previous scan in
file order, in that scan's frame, right perturbation ``ε = ⊖g ⊕ ĝ``; columns read by their
header names). Give runs as pairs of a results folder and its relations file; or ``--runs
DIR`` with ``DIR/NAME`` (or ``DIR/NAME/latest``) the results of the shared log ``NAME``,
whose relations are ``DATA/NAME/NAME.relations``; ``--run`` first runs ``fuzzypos run`` (the
default front end) on the shared logs, into ``--runs DIR`` or a temporary folder.

For each log:

1. the relations that span at most 10 s (``|t2 − t1|``) or at most 10 scans (steps apart in
   the trajectory's file order) are taken; each end is matched to the trajectory row of the
   nearest stamp, refused beyond 2 ms (counted as unmatched);
2. the steps of the scans after the first end up to and including the second, in file order
   (the order the steps were estimated in; intel's clocks go backwards, so stamp order may
   differ), are composed with their covariances (:func:`compose_steps`:
   ``Σ ← Ad(T₂⁻¹) Σ Ad(T₂⁻¹)ᵀ + Σ₂``); a relation whose second end comes first in the file
   takes the inverse chain (``Ad(T) Σ Ad(T)ᵀ``); one with a step whose covariance row is
   missing is skipped (counted);
3. the error ``e = ⊖ref ⊕ est`` as ``(x, y, θ)``, ``est = ⊖p1 ⊕ p2`` and ``ref`` the
   relation's motion; its squared Mahalanobis distance ``d² = eᵀ Σ⁻¹ e``;
4. "gross" errors: more than 0.3 m or 5°; "confident gross": gross and ``d² ≥ χ²₃(99.9 %)``
   (16.27) even under ``Σ + diag(0.02², 0.02², (0.5°)²)`` (the relations' own error, about
   a centimetre and a quarter degree, with a margin). Also the median ``d²`` under ``Σ``
   alone and the fraction of relations within 16.27 (0.999 for an honest covariance);
5. where the log is known (``--run``, ``--runs``, or ``--log NAME=LOG``), whether the scans
   themselves contradict the reference of each confident gross error
   (:func:`reference_contradicted`): the second end's scan laid on the first's by the
   reference's motion and by the estimate's, the points within ``ALIGN_RADIUS_M`` of the
   first scan's counted for each; the reference is contradicted where the estimate's count
   exceeds the reference's by ``ALIGN_SIGMAS`` standard deviations of the difference of two
   counts (a sign test's √(n₁ + n₂)). Those are counted apart: a benchmark's relations are
   hand-aligned, and a relation whose motion does not lay the two scans on each other at all
   while the estimate's does measures the reference, not the estimator. "Confident gross,
   reference sound" is the rest.

The table is printed and, unless ``--no-write``, written as markdown to ``--out`` (default
``docs/benchmarks/honesty.md``) with the date, commit, machine and command at the top, and as
JSON beside it.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import math
import os
import platform
import shlex
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from fuzzypos.config import Config
from fuzzypos.eval.metrics import nearest_stamps
from fuzzypos.geometry import compose_steps, inverse_covariance, relative
from fuzzypos.io import Relations, open_log, read_relations
from fuzzypos.io.provenance import git_hash, write_json
from fuzzypos.io.tum import read_tum

#: the shared logs, by name: the log and the relations under the data folder
LOGS = {
    name: (f"{name}/{name}.clf.gz", f"{name}/{name}.relations")
    for name in ("intel", "aces", "fr079", "fr-clinic")
}
#: the relations taken: at most this many seconds or this many scans (steps) long
MAX_SPAN_S = 10.0
MAX_SPAN_SCANS = 10
#: a relation's end and a trajectory row match within this many seconds
MAX_STAMP_GAP_S = 0.002
#: a gross error: beyond this translation (m) or rotation (degrees)
GROSS_TRANS_M = 0.3
GROSS_ROT_DEG = 5.0
#: the covariance added before calling a gross error confident (the relations' own error)
REFERENCE_SIGMA = (0.02, 0.02, math.radians(0.5))
#: χ² with 3 degrees of freedom, its 99.9 % quantile (scipy.stats.chi2.ppf(0.999, 3))
CHI2_3_999 = 16.266236196238129
#: a scan's point agrees with the other scan within this distance (m): above the range noise
#: and the sampling of a wall a few metres away, below a doorway's width
ALIGN_RADIUS_M = 0.1
#: the scans contradict the reference where the estimate lays this many standard deviations
#: (√(n₁ + n₂)) more points on the other scan than the reference does
ALIGN_SIGMAS = 3.0
#: covariance.csv's columns for the 3×3 matrix (upper triangle), by header name
COV_COLUMNS = {
    "xx": (0, 0),
    "xy": (0, 1),
    "xtheta": (0, 2),
    "yy": (1, 1),
    "ytheta": (1, 2),
    "thetatheta": (2, 2),
}


# -- reading a run ---------------------------------------------------------------------------
def read_covariance(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``covariance.csv``: the stamps ``(n,)`` and the covariances ``(n, 3, 3)``, the columns
    found by their header names (others, after them, are ignored)."""
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader)]
        missing = [k for k in ("stamp", *COV_COLUMNS) if k not in header]
        if missing:
            raise ValueError(f"{path}: no column(s) {', '.join(missing)} in the header")
        at = {k: header.index(k) for k in ("stamp", *COV_COLUMNS)}
        stamps: list[float] = []
        covs: list[np.ndarray] = []
        for row in reader:
            if not row or not "".join(row).strip():
                continue
            m = np.empty((3, 3))
            for k, (i, j) in COV_COLUMNS.items():
                m[i, j] = m[j, i] = float(row[at[k]])
            stamps.append(float(row[at["stamp"]]))
            covs.append(m)
    return np.array(stamps, dtype=float), np.array(covs, dtype=float).reshape(-1, 3, 3)


def align_covariances(
    traj_stamps: np.ndarray, cov_stamps: np.ndarray, covs: np.ndarray
) -> np.ndarray:
    """Each trajectory row's covariance ``(n, 3, 3)``: the covariance row of the same stamp
    (both files write it at full precision), rows of equal stamps taken in order; NaN where
    the trajectory row has none."""
    rows: dict[float, list[int]] = defaultdict(list)
    for k, t in enumerate(np.asarray(cov_stamps, dtype=float).tolist()):
        rows[t].append(k)
    out = np.full((len(traj_stamps), 3, 3), np.nan)
    taken: dict[float, int] = defaultdict(int)
    for k, t in enumerate(np.asarray(traj_stamps, dtype=float).tolist()):
        candidates = rows.get(t, [])
        if taken[t] < len(candidates):
            out[k] = covs[candidates[taken[t]]]
            taken[t] += 1
    return out


# -- the checks ------------------------------------------------------------------------------
class Honesty(NamedTuple):
    """One log's figures (module docstring). (Named tuples, not dataclasses: the tests load
    this script as a module outside ``sys.modules``, where a dataclass cannot be made.)"""

    relations: int  # in the file
    selected: int  # at most MAX_SPAN_S or MAX_SPAN_SCANS long (matched ends)
    unmatched: int  # an end with no trajectory row within MAX_STAMP_GAP_S
    no_covariance: int  # selected, but a step's covariance row is missing
    same_scan: int  # selected, both ends on one scan (nothing to compose)
    used: int
    gross: int
    confident_gross: int
    median_d2: float
    within_999: float  # the fraction of the used relations with d² <= CHI2_3_999
    #: confident gross errors whose reference the scans contradict (-1: not checked, no log)
    reference_contradicted: int = -1

    @property
    def confident_gross_sound(self) -> int:
        """Confident gross errors whose reference the scans do not contradict (-1: not
        checked)."""
        if self.reference_contradicted < 0:
            return -1
        return self.confident_gross - self.reference_contradicted

    def as_dict(self) -> dict[str, Any]:
        return {**self._asdict(), "confident_gross_sound": self.confident_gross_sound}


class RelationChecks(NamedTuple):
    """Per relation (the relations' order): whether it was used, its error ``(x, y, θ)``,
    the composed covariance, ``d²`` under it, ``d²`` with the reference's own error, whether
    it is a confident gross error, and its ends' trajectory rows."""

    used: np.ndarray
    error: np.ndarray
    covariance: np.ndarray
    d2: np.ndarray
    d2_widened: np.ndarray
    confident: np.ndarray  # confident gross errors
    ends: np.ndarray  # (n, 2): the trajectory rows of each relation's ends
    summary: Honesty


def mahalanobis2(e: np.ndarray, sigma: np.ndarray) -> float:
    """``eᵀ Σ⁻¹ e``; infinite for a singular Σ."""
    try:
        return float(e @ np.linalg.solve(sigma, e))
    except np.linalg.LinAlgError:
        return math.inf


def check_relations(
    stamps: np.ndarray,
    poses: np.ndarray,
    step_covariances: np.ndarray,
    relations: Relations,
    *,
    max_span_s: float = MAX_SPAN_S,
    max_span_scans: int = MAX_SPAN_SCANS,
    max_stamp_gap: float = MAX_STAMP_GAP_S,
) -> RelationChecks:
    """The module docstring's steps 1–4 on one trajectory: ``stamps`` ``(n,)`` and ``poses``
    ``(n, 3)`` in file order, ``step_covariances`` ``(n, 3, 3)`` (row ``k``: the step from
    row ``k − 1`` to ``k``; NaN where missing)."""
    t = np.asarray(stamps, dtype=float)
    p = np.asarray(poses, dtype=float).reshape(-1, 3)
    covs = np.asarray(step_covariances, dtype=float).reshape(-1, 3, 3)
    n_rel = len(relations)
    i1, g1 = nearest_stamps(t, relations.t1)
    i2, g2 = nearest_stamps(t, relations.t2)
    matched = (g1 <= max_stamp_gap) & (g2 <= max_stamp_gap)
    short = (np.abs(relations.t2 - relations.t1) <= max_span_s) | (
        np.abs(i2 - i1) <= max_span_scans
    )
    widen = np.diag(np.square(REFERENCE_SIGMA))
    used = np.zeros(n_rel, dtype=bool)
    error = np.full((n_rel, 3), np.nan)
    sigma_all = np.full((n_rel, 3, 3), np.nan)
    d2 = np.full(n_rel, np.nan)
    d2w = np.full(n_rel, np.nan)
    unmatched = int(np.sum(~matched))
    no_cov = same = 0
    for r in np.flatnonzero(short & matched):
        a, b = int(i1[r]), int(i2[r])
        if a == b:
            same += 1
            continue
        lo, hi = min(a, b), max(a, b)
        chain = covs[lo + 1 : hi + 1]
        if not np.all(np.isfinite(chain)):
            no_cov += 1
            continue
        steps = relative(p[lo:hi], p[lo + 1 : hi + 1])
        motion, sigma = compose_steps(steps, chain)
        if b < a:
            sigma = inverse_covariance(motion, sigma)
        est = relative(p[a], p[b])
        e = relative(relations.motion[r], est)
        used[r] = True
        error[r], sigma_all[r] = e, sigma
        d2[r] = mahalanobis2(e, sigma)
        d2w[r] = mahalanobis2(e, sigma + widen)
    gross = used & (
        (np.hypot(error[:, 0], error[:, 1]) > GROSS_TRANS_M)
        | (np.abs(error[:, 2]) > math.radians(GROSS_ROT_DEG))
    )
    confident = gross & (d2w >= CHI2_3_999)
    ends = np.stack([i1, i2], axis=1)
    n_used = int(used.sum())
    summary = Honesty(
        relations=n_rel,
        selected=int(np.sum(short & matched)),
        unmatched=unmatched,
        no_covariance=no_cov,
        same_scan=same,
        used=n_used,
        gross=int(gross.sum()),
        confident_gross=int(confident.sum()),
        median_d2=float(np.median(d2[used])) if n_used else math.nan,
        within_999=float(np.mean(d2[used] <= CHI2_3_999)) if n_used else math.nan,
    )
    return RelationChecks(used, error, sigma_all, d2, d2w, confident, ends, summary)


def agreement(first: np.ndarray, second: np.ndarray, motion: np.ndarray, radius: float) -> int:
    """How many of the ``second`` scan's points ``(m, 2)`` (robot frame) lie within
    ``radius`` of the ``first`` scan's ``(n, 2)`` once moved into its frame by ``motion``
    (the pose of the second in the frame of the first)."""
    if first.shape[0] == 0 or second.shape[0] == 0:
        return 0
    x, y, th = (float(v) for v in motion)
    c, s = math.cos(th), math.sin(th)
    moved = second @ np.array([[c, s], [-s, c]]) + (x, y)
    d, _ = cKDTree(first).query(moved, distance_upper_bound=radius)
    return int(np.count_nonzero(np.isfinite(d)))


def reference_contradicted(
    first: np.ndarray,
    second: np.ndarray,
    reference: np.ndarray,
    estimate: np.ndarray,
    *,
    radius: float = ALIGN_RADIUS_M,
    sigmas: float = ALIGN_SIGMAS,
) -> bool:
    """Whether two scans' points contradict a relation's ``reference`` motion: the
    ``estimate`` lays decisively more of the second scan on the first (:func:`agreement`;
    ``sigmas`` standard deviations of the difference of the two counts, √(n₁ + n₂))."""
    n_ref = agreement(first, second, reference, radius)
    n_est = agreement(first, second, estimate, radius)
    return n_est - n_ref > sigmas * math.sqrt(max(n_ref + n_est, 1))


def scan_points(log: Path, stamps: np.ndarray, rows: set[int]) -> dict[int, np.ndarray]:
    """The valid points (robot frame; the default "no return" bands left out) of the log's
    scans at the trajectory ``rows`` (in file order; a scan whose stamp is not the row's
    within ``MAX_STAMP_GAP_S`` is left out)."""
    out: dict[int, np.ndarray] = {}
    bands = Config().scanner.no_return_bands
    k = 0
    for rec in open_log(log).records():
        if rec.scan is None:
            continue
        if k in rows and abs(rec.scan.stamp - float(stamps[k])) <= MAX_STAMP_GAP_S:
            xy = rec.scan.points_robot(bands)
            out[k] = xy[np.isfinite(xy).all(axis=1)]
        k += 1
        if k >= len(stamps) or k > max(rows, default=-1):
            break
    return out


def check_run(results: Path, relations_path: Path, log: Path | None = None) -> Honesty:
    """:func:`check_relations` on a results folder against a relations file; with the
    ``log``, also which confident gross errors the scans contradict the reference of."""
    stamps, poses = read_tum(results / "trajectory.tum")
    cov_stamps, covs = read_covariance(results / "covariance.csv")
    step_covs = align_covariances(stamps, cov_stamps, covs)
    relations = read_relations(relations_path)
    checks = check_relations(stamps, poses, step_covs, relations)
    if log is None:
        return checks.summary
    which = np.flatnonzero(checks.confident)
    rows = {int(r) for pair in checks.ends[which] for r in pair}
    points = scan_points(log, stamps, rows)
    contradicted = 0
    for r in which:
        a, b = (int(v) for v in checks.ends[r])
        if a in points and b in points:
            est = relative(poses[a], poses[b])
            contradicted += reference_contradicted(points[a], points[b], relations.motion[r], est)
    return checks.summary._replace(reference_contradicted=contradicted)


# -- finding and making runs -----------------------------------------------------------------
def results_folder(runs: Path, name: str) -> Path:
    """``runs/name`` if it holds a trajectory, else ``runs/name/latest``."""
    for folder in (runs / name, runs / name / "latest"):
        if (folder / "trajectory.tum").exists():
            return folder
    raise FileNotFoundError(f"{runs / name}: no trajectory.tum (nor in latest/)")


def run_front_end(log: Path, results: Path, extra: list[str]) -> None:
    """``fuzzypos run LOG --results RESULTS --overwrite [extra]`` with this interpreter."""
    cmd = [
        sys.executable,
        "-c",
        "import sys; from fuzzypos.cli import app; sys.argv[0] = 'fuzzypos'; app()",
        "run",
        os.fspath(log),
        "--results",
        os.fspath(results),
        "--overwrite",
        *extra,
    ]
    print(f"running: fuzzypos {shlex.join(cmd[3:])}", file=sys.stderr, flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


# -- the report ------------------------------------------------------------------------------
HEADER = (
    "| log | relations used | gross errors | confident gross errors | of them, reference "
    "contradicted by the scans | confident gross, reference sound | median d² "
    "| fraction d² ≤ 16.27 | unmatched | no covariance |"
)


def table(rows: list[tuple[str, Honesty]]) -> str:
    lines = [HEADER, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, h in rows:
        med = "–" if not math.isfinite(h.median_d2) else f"{h.median_d2:.2f}"
        frac = "–" if not math.isfinite(h.within_999) else f"{h.within_999:.3f}"
        contra = "–" if h.reference_contradicted < 0 else str(h.reference_contradicted)
        sound = "–" if h.confident_gross_sound < 0 else str(h.confident_gross_sound)
        lines.append(
            f"| {name} | {h.used} | {h.gross} | {h.confident_gross} | {contra} | {sound} "
            f"| {med} | {frac} | {h.unmatched} | {h.no_covariance} |"
        )
    return "\n".join(lines)


def machine() -> str:
    """The platform and the CPU model (``/proc/cpuinfo`` where there is one)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{platform.platform()}, {cpu}, {os.cpu_count()} CPUs"


def commit() -> str:
    """The commit this checkout is at, marked where its code (``src``, ``benchmarks``)
    differs from it."""
    h = git_hash() or "unknown"
    try:
        top = Path(__file__).resolve().parent.parent
        dirty = subprocess.run(
            ["git", "-C", os.fspath(top), "status", "--porcelain", "--untracked-files=no"]
            + ["--", "src", "benchmarks"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        return f"{h} (with uncommitted changes)" if dirty else h
    except Exception:
        return h


def markdown(rows: list[tuple[str, Honesty]], meta: dict[str, str]) -> str:
    return (
        "# Covariance honesty on short relations (issue 34, item 2)\n\n"
        f"- date: {meta['date']}\n"
        f"- commit: {meta['commit']}\n"
        f"- machine: {meta['machine']}\n"
        f"- command: `{meta['command']}`\n"
        f"- data: {meta['data']}\n"
        f"- runs: {meta['runs']}\n\n"
        "Relations at most 10 s or 10 scans long, ends matched within 2 ms; the step "
        "covariances composed along each (right perturbations); error e = ⊖ref ⊕ est. "
        "Gross: more than 0.3 m or 5°; confident gross: gross and d² ≥ 16.27 (χ²₃ at 99.9 %) "
        "under Σ + diag(0.02², 0.02², (0.5°)²). Median d² and the fraction within 16.27 under "
        "Σ alone (honest: about 2.37 and 0.999). Where the log is at hand, each confident gross "
        "error's two scans are laid on each other by the reference's motion and by the "
        "estimate's: the reference is contradicted by the scans where the estimate puts "
        f"{ALIGN_SIGMAS:g} σ (√(n₁ + n₂)) more of the second scan within {ALIGN_RADIUS_M:g} m "
        "of the first (the relations are hand-aligned; such a relation measures the "
        "reference, not the estimator). `benchmarks/bench_honesty.py`'s docstring has the "
        "details.\n\n" + table(rows) + "\n"
    )


def main(argv: list[str] | None = None) -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "pairs",
        nargs="*",
        type=Path,
        help="RESULTS RELATIONS pairs: a results folder and its log's relations file",
    )
    ap.add_argument(
        "--data",
        default=os.environ.get("FUZZYPOS_DATA", os.fspath(here.parent.parent / "shared" / "data")),
        help="the shared data folder (default: $FUZZYPOS_DATA, else ../shared/data)",
    )
    ap.add_argument(
        "--runs", type=Path, default=None, help="a folder with a results folder per shared log"
    )
    ap.add_argument(
        "--logs", default=",".join(LOGS), help=f"with --runs or --run: of {', '.join(LOGS)}"
    )
    ap.add_argument(
        "--run",
        action="store_true",
        help="run `fuzzypos run` on the shared logs first (into --runs, else a temporary folder)",
    )
    ap.add_argument(
        "--run-arg",
        action="append",
        default=[],
        help="with --run: an argument for `fuzzypos run` (repeat; e.g. --run-arg=--preset=paper)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=here.parent / "docs" / "benchmarks" / "honesty.md",
        help="the markdown to write (a JSON beside it); default docs/benchmarks/honesty.md",
    )
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args(argv)
    if len(args.pairs) % 2:
        ap.error("runs come as RESULTS RELATIONS pairs")
    names = [s.strip() for s in args.logs.split(",") if s.strip()]
    unknown = [n for n in names if n not in LOGS]
    if unknown:
        ap.error(f"--logs: unknown {', '.join(unknown)} (known: {', '.join(LOGS)})")
    if not args.pairs and args.runs is None and not args.run:
        ap.error("give RESULTS RELATIONS pairs, --runs DIR or --run")

    data = Path(args.data)
    jobs: list[tuple[str, Path, Path, Path | None]] = [
        (args.pairs[k + 1].name.removesuffix(".relations"), args.pairs[k], args.pairs[k + 1], None)
        for k in range(0, len(args.pairs), 2)
    ]
    scratch = None
    runs_note = ", ".join(os.fspath(p) for _, p, _, _ in jobs) or ""
    if args.run or args.runs is not None:
        if args.run and args.runs is None:
            scratch = tempfile.TemporaryDirectory(prefix="bench-honesty-")
        runs = args.runs if args.runs is not None else Path(scratch.name)  # type: ignore[union-attr]
        for name in names:
            log, rel = (data / part for part in LOGS[name])
            if args.run:
                if not log.exists():
                    sys.exit(f"{log}: missing; see --data")
                run_front_end(log, runs / name, args.run_arg)
            jobs.append((name, results_folder(runs, name), rel, log if log.exists() else None))
        if args.run:
            how = " ".join(["fuzzypos run LOG", *args.run_arg])
            runs_note = f"`{how}` on the shared logs, this commit, just before"
        else:
            runs_note = f"the results folders under {runs.name}"

    rows: list[tuple[str, Honesty]] = []
    for name, results, rel, log in jobs:
        rows.append((name, check_run(results, rel, log)))
    if scratch is not None:
        scratch.cleanup()
    text = table(rows)
    print(text)
    if args.no_write:
        return
    meta = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": commit(),
        "machine": machine(),
        "command": shlex.join(["python", "benchmarks/bench_honesty.py", *sys.argv[1:]])
        if argv is None
        else shlex.join(["python", "benchmarks/bench_honesty.py", *argv]),
        "runs": runs_note,
        "data": os.path.relpath(data, here.parent),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(markdown(rows, meta), encoding="utf-8")
    write_json(
        args.out.with_suffix(".json"),
        {
            **meta,
            "settings": {
                "max_span_s": MAX_SPAN_S,
                "max_span_scans": MAX_SPAN_SCANS,
                "max_stamp_gap_s": MAX_STAMP_GAP_S,
                "gross_trans_m": GROSS_TRANS_M,
                "gross_rot_deg": GROSS_ROT_DEG,
                "reference_sigma": REFERENCE_SIGMA,
                "chi2_3_999": CHI2_3_999,
                "align_radius_m": ALIGN_RADIUS_M,
                "align_sigmas": ALIGN_SIGMAS,
            },
            "rows": [{"log": name, **h.as_dict()} for name, h in rows],
        },
    )
    print(f"\nwritten: {args.out} and {args.out.with_suffix('.json').name}", file=sys.stderr)


if __name__ == "__main__":
    main()
