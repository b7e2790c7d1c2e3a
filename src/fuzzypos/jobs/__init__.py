"""The jobs the command line runs: a run over one log and its results folder (:mod:`.run`,
:mod:`.outputs`, :mod:`.folders`), the benchmark (:mod:`.benchmark`), many runs as Ray tasks
(:mod:`.batch`, :mod:`.tasks`), the simulated demo (:mod:`.demo`) and localisation in a saved
map (:mod:`.localize`)."""

from __future__ import annotations

from .batch import BatchResult, run_batch
from .benchmark import BenchmarkResult, run_benchmark
from .demo import DemoResult, DemoSettings, run_demo
from .folders import ResultsFolder, ResultsFolderError, default_results_dir, log_name
from .localize import LocalizeSummary, localize_log, localize_partial
from .run import PartialRunError, RunJob, RunSummary, partial_results, run_log, write_estimate_clf
from .tasks import TaskDone, run_tasks

__all__ = [
    "BatchResult",
    "BenchmarkResult",
    "DemoResult",
    "DemoSettings",
    "LocalizeSummary",
    "PartialRunError",
    "ResultsFolder",
    "ResultsFolderError",
    "RunJob",
    "RunSummary",
    "TaskDone",
    "default_results_dir",
    "localize_log",
    "localize_partial",
    "log_name",
    "partial_results",
    "run_batch",
    "run_benchmark",
    "run_demo",
    "run_log",
    "run_tasks",
    "write_estimate_clf",
]
