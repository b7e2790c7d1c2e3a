"""The run job as one object over its output sinks (:class:`fuzzypos.jobs.RunJob`,
:mod:`fuzzypos.jobs.sinks`): a typed summary that is ``summary.json`` (:class:`RunSummary`),
a partial run's :class:`PartialRunError` carrying it, ``trajectory.clf`` written once at the
final poses (loop closure's too), and a CARMEN log read twice per run (the survey, the run)."""

from __future__ import annotations

import errno
import json
import os

import numpy as np
import pytest

import fuzzypos.io.carmen as carmen
import fuzzypos.io.carmen_write as carmen_write
from fuzzypos.config import Config
from fuzzypos.io import CarmenReader, open_log, read_tum
from fuzzypos.jobs import PartialRunError, RunSummary, partial_results, run_log
from helpers import write_sim_log


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("sinks") / "sim.clf"
    return path, write_sim_log(path)


def test_the_summary_is_summary_json(sim_log, tmp_path) -> None:
    path, run = sim_log
    res = run_log(path, results_dir=tmp_path / "r", plot=False)
    assert isinstance(res, RunSummary) and not res.partial and res.scans == len(run)
    on_disk = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert json.loads(json.dumps(res.to_json())) == on_disk
    assert list(res.to_json()) == list(on_disk)  # the keys in summary.json's order
    assert res.bad_lines_skipped == on_disk["bad_lines_skipped"] == 0
    assert res.positioner_ms_per_scan == on_disk["positioner_ms_per_scan"]
    assert res.files["summary.json"] == tmp_path / "r" / "summary.json"
    assert on_disk["files"] == {k: str(v) for k, v in res.files.items()}


def test_a_run_stopped_by_an_error_raises_what_it_kept(sim_log, tmp_path) -> None:
    path, _ = sim_log
    lines = path.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("FLASER")) + 10
    bad = tmp_path / "bad.clf"
    bad.write_text("".join([*lines[:k], "FLASER 3 1 2\n", *lines[k:]]))
    with pytest.raises(PartialRunError) as info:
        run_log(bad, results_dir=tmp_path / "r", plot=False)
    exc = info.value
    assert isinstance(exc, ValueError) and not isinstance(exc, OSError)
    assert isinstance(exc.stopped, carmen.CarmenFormatError) and exc.__cause__ is exc.stopped
    assert str(exc) == " ".join(str(exc.stopped).split())
    assert exc.summary is partial_results(exc) and exc.summary.partial
    assert exc.summary.partial_reason is not None
    assert exc.summary.partial_reason.startswith("failed at scan 5: ")
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["scans"] == 4


def test_ctrl_c_is_the_interrupt_with_what_was_kept_behind_it(sim_log, tmp_path) -> None:
    path, _ = sim_log

    def stop(done: int, total: int | None) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as info:
        run_log(path, results_dir=tmp_path / "r", progress=stop, plot=False)
    assert isinstance(info.value.__cause__, PartialRunError)
    kept = partial_results(info.value)
    assert kept is not None and kept.scans == 25 and kept.partial_reason == "interrupted at scan 26"
    assert partial_results(KeyboardInterrupt()) is None and partial_results(ValueError()) is None


def test_a_full_disk_is_an_os_error_too(sim_log, tmp_path, monkeypatch) -> None:
    import fuzzypos.jobs.sinks as sinks

    path, _ = sim_log

    class Full:
        def __init__(self, fh) -> None:
            self.fh, self.rows = fh, 0

        def write(self, text: str) -> int:
            self.rows += 1
            if self.rows == 4:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return self.fh.write(text)

        def close(self) -> None:
            self.fh.close()

    opener = lambda *a, **k: Full(open(*a, **k))  # noqa: E731, SIM115 (closed by close)
    monkeypatch.setattr(sinks, "open", opener, raising=False)
    with pytest.raises(OSError, match=os.strerror(errno.ENOSPC)) as info:
        run_log(path, results_dir=tmp_path / "r", plot=False)
    assert isinstance(info.value, PartialRunError) and info.value.summary.scans == 2


def test_a_carmen_log_is_read_twice(sim_log, tmp_path, monkeypatch) -> None:
    """The survey (which takes the stamps too) and the run: not a third pass for the stamps'
    check and the progress total."""
    path, run = sim_log
    opened: list[str] = []
    real = carmen.open_text

    def counting(p, *a, **k):
        opened.append(str(p))
        return real(p, *a, **k)

    monkeypatch.setattr(carmen, "open_text", counting)
    calls: list[tuple[int, int | None]] = []
    log = open_log(path)
    run_log(log, results_dir=tmp_path / "r", plot=False, progress=lambda d, t: calls.append((d, t)))
    assert opened == [str(path), str(path)]
    assert calls[-1] == (len(run), len(run))  # the total, from the survey's stamps
    assert log.scan_stamps().tolist() == list(run.stamps)
    assert log.reader.scan_stamps().tolist() == log.scan_stamps().tolist()


def test_trajectory_clf_is_written_once_at_the_optimised_poses(tmp_path, monkeypatch) -> None:
    pytest.importorskip("gtsam", reason="loop closure needs gtsam (pip install 'fuzzypos[graph]')")
    path = tmp_path / "loop.clf"
    run = write_sim_log(path, laps=1.3, seed=0)
    written: list[int] = []
    real = carmen_write._held_text
    monkeypatch.setattr(carmen_write, "_held_text", lambda h, p: written.append(1) or real(h, p))
    opened: list[str] = []

    def watched(p, mode="r", *a, **k):
        opened.append(mode)
        return open(p, mode, *a, **k)

    monkeypatch.setattr(carmen_write, "open", watched, raising=False)
    cfg = Config().with_overrides({"loop_closure": {"enabled": True}})
    res = run_log(path, cfg, results_dir=tmp_path / "r", plot=False)
    assert res.loop_closure is not None and len(written) == len(run)
    assert opened == ["w"]  # the temporary file, once: never read back
    out = tmp_path / "r"
    text = (out / "trajectory.clf").read_text()
    assert "# x y theta after loop closure: the optimised poses\n" in text
    est = [ln.split() for ln in text.splitlines() if ln.startswith("FLASER")]
    poses = np.array([[float(v) for v in t[2 + int(t[1]) : 5 + int(t[1])]] for t in est])
    _stamps, tum = read_tum(out / "trajectory.tum")
    np.testing.assert_allclose(poses, tum, atol=1e-9)
    assert not np.allclose(poses, res.frontend_poses)  # loop closure moved them
    assert len(list(CarmenReader(out / "trajectory.clf").records())) == len(run)
