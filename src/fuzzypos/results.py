"""Compatibility names: what ``fuzzypos.results`` held before it was split (issue 9).

- the run job (:func:`run_log`, :class:`RunSummary`, :func:`default_results_dir`,
  :func:`log_name`, :func:`write_estimate_clf`): :mod:`fuzzypos.run`;
- scoring a trajectory file (:func:`evaluate_trajectory`, :class:`Evaluation`):
  :mod:`fuzzypos.scoring`;
- the benchmark (:func:`find_benchmark_logs`, :func:`run_benchmark`,
  :class:`BenchmarkResult`, :data:`BENCHMARK_CONFIGS`): :mod:`fuzzypos.benchmark`;
- provenance (:func:`file_sha256`, :func:`git_hash`): :mod:`fuzzypos.provenance`.

Nothing inside the package imports this module; new code should import from the modules
above.
"""

from __future__ import annotations

from .benchmark import BENCHMARK_CONFIGS, BenchmarkResult, find_benchmark_logs, run_benchmark
from .provenance import file_sha256, git_hash
from .run import RunSummary, default_results_dir, log_name, run_log, write_estimate_clf
from .scoring import Evaluation, evaluate_trajectory

__all__ = [
    "BENCHMARK_CONFIGS",
    "BenchmarkResult",
    "Evaluation",
    "RunSummary",
    "default_results_dir",
    "evaluate_trajectory",
    "file_sha256",
    "find_benchmark_logs",
    "git_hash",
    "log_name",
    "run_benchmark",
    "run_log",
    "write_estimate_clf",
]
