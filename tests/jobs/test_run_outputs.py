"""Where a run writes, and what it keeps when stopped after its loop (issue 35).

An output path is written where it points: through a symlink to its target, to a pipe, FIFO
or character device directly (never replaced); anything else is refused before the run. An
unwritable path is refused before the run, a full disk names the file and keeps what was
written (``"partial": true``). A results folder is locked by the run that owns it. Ctrl-C
after the loop (loop closure's final optimisation, the writers) keeps what was done.

Devices are character devices made in ``tmp_path`` (``os.mknod``: a copy of /dev/null or
/dev/full), so that nothing here can replace a real /dev file; /dev/null itself is written
only after the fixed code path says it streams to it.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import select
import socket
import stat
import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.jobs import run_log
from fuzzypos.pipeline import Positioner
from helpers import write_sim_log

runner = CliRunner()
_UPDATE = Positioner.update


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("outputs") / "sim.clf"
    return path, write_sim_log(path)


def lines_of(res) -> list[str]:
    return [ln for ln in res.output.splitlines() if ln.strip()]


def never_run(monkeypatch: pytest.MonkeyPatch) -> None:
    def never(self, scan, odometry):
        raise AssertionError("the run started")

    monkeypatch.setattr(Positioner, "update", never)


def refused(args: list[str], expect: str) -> str:
    """The CLI's one line and exit 2, with no traceback."""
    res = runner.invoke(app, args)
    assert res.exit_code == 2 and "Traceback" not in res.output, (args, res.output)
    (line,) = lines_of(res)
    assert line.startswith("fuzzypos: error: ") and expect in line, line
    return line


def hidden(folder: Path) -> list[str]:
    """What a run left that is not a result: temporary files, the lock."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def tum_rows(path: Path) -> int:
    return sum(1 for ln in path.read_text().splitlines() if ln and not ln.startswith("#"))


def char_device(path: Path, minor: int) -> Path:
    """A character device at ``path``: memory device ``minor`` (3: null, 7: full)."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, minor))
        with open(path, "wb"):
            pass
    except OSError as exc:  # no CAP_MKNOD, or a nodev file system
        pytest.skip(f"cannot make a character device here: {exc}")
    return path


# -- where an output path points -------------------------------------------------------------
def test_o_through_a_symlink_writes_its_target_and_keeps_the_link(sim_log, tmp_path):
    path, run = sim_log
    (tmp_path / "real").mkdir()
    target = tmp_path / "real" / "x.tum"
    target.write_text("old\n")
    link = tmp_path / "link.tum"
    link.symlink_to(target)
    dangling = tmp_path / "new.tum"
    dangling.symlink_to(tmp_path / "real" / "new.tum")
    res = run_log(path, results_dir=tmp_path / "res", out_tum=link, plot=False)
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert tum_rows(target) == res.scans == len(run)
    run_log(path, results_dir=tmp_path / "res2", out_tum=dangling, plot=False)
    assert dangling.is_symlink() and tum_rows(tmp_path / "real" / "new.tum") == len(run)
    assert hidden(tmp_path / "real") == []


def test_o_to_a_fifo_streams_into_it(sim_log, tmp_path):
    path, _run = sim_log
    fifo = tmp_path / "out.tum"
    os.mkfifo(fifo)
    got: list[bytes] = []
    opened = threading.Event()

    def read() -> None:  # never blocks for good: the test fails, it does not hang
        fd = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
        opened.set()
        deadline = 60.0
        try:
            while deadline > 0:
                ready, _, _ = select.select([fd], [], [], 0.1)
                deadline -= 0.1
                if ready:
                    chunk = os.read(fd, 1 << 16)
                    if not chunk and got:
                        return
                    got.append(chunk)
        finally:
            os.close(fd)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    opened.wait(10)
    res = run_log(path, results_dir=tmp_path / "res", out_tum=fifo, plot=False)
    reader.join(30)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)  # not replaced by a file
    text = b"".join(got).decode()
    assert sum(1 for ln in text.splitlines() if ln and not ln.startswith("#")) == res.scans
    assert res.files["out_tum"] == fifo and hidden(tmp_path) == []


def test_o_to_a_pipe_by_its_dev_fd_name_streams_into_it(sim_log, tmp_path):
    """``-o >(cat > x.tum)``: the shell gives ``/dev/fd/N``, a pipe."""
    path, run = sim_log
    r, w = os.pipe()
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.extend(iter(lambda: os.read(r, 1 << 16), b"")))
    reader.start()
    try:
        res = run_log(path, results_dir=tmp_path / "res", out_tum=f"/dev/fd/{w}", plot=False)
    finally:
        os.close(w)
        reader.join(30)
        os.close(r)
    text = b"".join(got).decode()
    assert sum(1 for ln in text.splitlines() if ln and not ln.startswith("#")) == len(run)
    assert json.loads((tmp_path / "res" / "summary.json").read_text())["partial"] is False
    assert res.files["out_tum"] == Path(f"/dev/fd/{w}")


def test_o_to_a_character_device_writes_to_it_and_keeps_it(sim_log, tmp_path):
    path, _run = sim_log
    null = char_device(tmp_path / "null", 3)
    res = runner.invoke(app, ["run", str(path), "--results", str(tmp_path / "r"), "-o", str(null)])
    assert res.exit_code == 0, res.output
    assert stat.S_ISCHR(os.lstat(null).st_mode)
    assert hidden(tmp_path) == []


def test_dev_null_is_streamed_to_never_replaced(sim_log, tmp_path):
    from fuzzypos.io import output_target  # (before /dev/null is ever written)

    assert output_target("/dev/null") == (Path("/dev/null"), True)
    path, _run = sim_log
    res = run_log(path, results_dir=tmp_path / "res", out_tum="/dev/null", plot=False)
    assert res.files["out_tum"] == Path("/dev/null")
    assert stat.S_ISCHR(os.lstat("/dev/null").st_mode)


def test_o_to_a_socket_or_a_folder_is_refused_before_the_run(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    never_run(monkeypatch)
    monkeypatch.chdir(tmp_path)
    with socket.socket(socket.AF_UNIX) as sock:
        sock.bind("s.tum")
        refused(["run", str(path), "-o", "s.tum"], "s.tum: is a socket, not a file")
    assert stat.S_ISSOCK(os.lstat("s.tum").st_mode)
    Path("d").mkdir()
    refused(["run", str(path), "-o", "d"], "d: is a folder")
    assert not Path("results").exists()


# -- unwritable paths --------------------------------------------------------------------------
def read_only(monkeypatch: pytest.MonkeyPatch, folder: Path) -> None:
    """``folder`` read-only: by its mode, and, for root (whom modes do not stop), by
    refusing to create anything in it."""
    folder.chmod(0o555)
    monkeypatch.setattr(os, "open", _refusing(os.open, folder))


def _refusing(real, folder: Path):
    def fake(name, flags, *args, **kwargs):
        if flags & os.O_CREAT and Path(os.fsdecode(name)).parent == folder:
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fsdecode(name))
        return real(name, flags, *args, **kwargs)

    return fake


def test_an_unwritable_results_folder_is_refused_before_the_run(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    ro = tmp_path / "ro"
    ro.mkdir()
    read_only(monkeypatch, ro)
    never_run(monkeypatch)
    try:
        refused(["run", str(path), "--results", str(ro)], f"{ro}: cannot be written")
        refused(["run", str(path), "-o", str(ro / "x.tum")], f"{ro} is read-only")
    finally:
        ro.chmod(0o755)
    assert list(ro.iterdir()) == []


def test_a_path_under_a_file_is_refused_before_the_run(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    never_run(monkeypatch)
    (tmp_path / "f").write_text("")
    under = str(tmp_path / "f" / "sub")
    refused(["run", str(path), "--results", under], f"{tmp_path / 'f'} is a file, not a folder")
    refused(["run", str(path), "-o", under + ".tum"], "is a file, not a folder")
    refused(["run", str(path), "--bag-out", under + ".bag"], "is a file, not a folder")


# -- a full disk -------------------------------------------------------------------------------
def test_a_full_device_names_the_file_and_keeps_the_results(sim_log, tmp_path):
    path, run = sim_log
    full = char_device(tmp_path / "full", 7)
    out = tmp_path / "res"
    line = refused(
        ["run", str(path), "--results", str(out), "-o", str(full)],
        f"cannot write {full}: No space left on device",
    )
    assert line.endswith(
        f"(after the {len(run)} scans; the results of the {len(run)} scans are kept in {out}/ "
        '(summary.json: "partial": true))'
    )
    assert stat.S_ISCHR(os.lstat(full).st_mode)
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] is True and "No space left on device" in s["partial_reason"]
    assert tum_rows(out / "trajectory.tum") == len(run) and (out / "trajectory.clf").exists()
    assert not (out / "path.png").exists() and hidden(out) == []


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EFBIG])
def test_a_full_results_folder_names_the_file(sim_log, tmp_path, monkeypatch, code):
    """A file of the folder cannot be written (simulated where files are written): the rest
    is, summary.json says partial; where summary.json cannot be, the line says so."""
    from fuzzypos.io import _common

    path, _run = sim_log
    real = _common._write_to
    full = {"trajectory.tum"}

    def write_to(target, gz, write):
        if any(Path(target).name.startswith(f".{name}.") for name in full):
            raise OSError(code, os.strerror(code))
        return real(target, gz, write)

    monkeypatch.setattr(_common, "_write_to", write_to)
    out = tmp_path / "res"
    why = os.strerror(code)
    refused(["run", str(path), "--results", str(out)], f"cannot write {out}/trajectory.tum: {why}")
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] and s["partial_reason"].endswith(f"trajectory.tum: {why}")
    assert "trajectory.tum" not in s["files"] and (out / "covariance.csv").exists()
    assert hidden(out) == []
    full.add("summary.json")
    out2 = tmp_path / "res2"
    line = refused(["run", str(path), "--results", str(out2)], "cannot write")
    assert line.endswith("(summary.json could not be written))")
    assert not (out2 / "summary.json").exists() and hidden(out2) == []


def test_a_file_too_large_mid_run_names_it_and_keeps_the_scans_before(
    sim_log, tmp_path, monkeypatch
):
    """covariance.csv, written scan by scan, fails at its 6th row (EFBIG)."""
    import fuzzypos.jobs.sinks as run_outputs

    path, _run = sim_log

    class Full:
        def __init__(self, fh) -> None:
            self.fh, self.rows = fh, 0

        def write(self, text: str) -> int:
            self.rows += 1
            if self.rows == 7:  # the header, then 5 rows
                raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))
            return self.fh.write(text)

        def close(self) -> None:
            self.fh.close()

    opener = lambda *a, **k: Full(open(*a, **k))  # noqa: E731, SIM115 (closed by close)
    monkeypatch.setattr(run_outputs, "open", opener, raising=False)
    out = tmp_path / "res"
    line = refused(
        ["run", str(path), "--results", str(out)],
        f"cannot write {out}/covariance.csv: {os.strerror(errno.EFBIG)} (stopped at scan 6; "
        "the 5 scans before it are kept",
    )
    assert line.endswith('(summary.json: "partial": true))')
    s = json.loads((out / "summary.json").read_text())
    assert s["partial_reason"].startswith("failed at scan 6: cannot write")
    assert tum_rows(out / "trajectory.tum") == 5 and hidden(out) == []


# -- one run per folder ------------------------------------------------------------------------
def test_a_folder_in_use_by_another_run_is_refused(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    out = tmp_path / "res"
    out.mkdir()
    with open(out / ".fuzzypos.lock", "w") as held:  # another run's lock
        fcntl.flock(held, fcntl.LOCK_EX)
        held.write("4242\n")
        held.flush()
        never_run(monkeypatch)
        for extra in ([], ["--overwrite"]):
            refused(
                ["run", str(path), "--results", str(out), *extra],
                f"results folder {out} is in use by another run (pid 4242)",
            )
    monkeypatch.setattr(Positioner, "update", _UPDATE)
    res = runner.invoke(app, ["run", str(path), "--results", str(out), "--max-scans", "3"])
    assert res.exit_code == 0, res.output
    assert hidden(out) == []  # the lock is gone with its run


def test_the_run_holds_its_folder_until_it_ends(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    out = tmp_path / "res"
    seen: list[str] = []

    def update(self, scan, odometry):
        if not seen:  # a second run, while this one positions
            seen.append(runner.invoke(app, ["run", str(path), "--results", str(out)]).output)
        return _UPDATE(self, scan, odometry)

    monkeypatch.setattr(Positioner, "update", update)
    run_log(path, results_dir=out, plot=False, max_scans=5)
    assert f"results folder {out} is in use by another run (pid {os.getpid()})" in seen[0]
    assert json.loads((out / "summary.json").read_text())["scans"] == 5


# -- Ctrl-C after the loop ---------------------------------------------------------------------
def ctrl_c(*_args, **_kwargs):
    raise KeyboardInterrupt


def numba_ctrl_c(*_args, **_kwargs):
    """What a compiled call raises when Ctrl-C arrives inside it."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as exc:
        raise SystemError(
            "CPUDispatcher(<function refine>) returned a result with an exception set"
        ) from exc


def test_ctrl_c_inside_the_loop_from_numba_is_an_interrupt(sim_log, tmp_path, monkeypatch):
    path, _run = sim_log
    calls: list[int] = []

    def update(self, scan, odometry):
        calls.append(1)
        if len(calls) == 4:
            numba_ctrl_c()
        return _UPDATE(self, scan, odometry)

    monkeypatch.setattr(Positioner, "update", update)
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--results", str(out)])
    assert res.exit_code == 130 and "Traceback" not in res.output, res.output
    assert lines_of(res)[0].startswith("fuzzypos: interrupted at scan 4; the 3 scans")
    assert (
        json.loads((out / "summary.json").read_text())["partial_reason"] == "interrupted at scan 4"
    )


@pytest.mark.parametrize("step", ["path.png", "config.toml"])
def test_ctrl_c_in_a_writer_keeps_the_rest(sim_log, tmp_path, monkeypatch, step):
    import fuzzypos.jobs.sinks as sinks

    path, run = sim_log
    if step == "path.png":
        monkeypatch.setattr(sinks.PlotSink, "close", ctrl_c)
    else:
        monkeypatch.setattr(sinks, "write_text_file", numba_ctrl_c)
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--results", str(out)])
    assert res.exit_code == 130 and "Traceback" not in res.output, res.output
    assert lines_of(res) == [
        (
            f"fuzzypos: interrupted while writing {step}; the results of the {len(run)} scans "
            f'are kept in {out}/ (summary.json: "partial": true)'
        )
    ]
    s = json.loads((out / "summary.json").read_text())
    assert s["partial"] is True and s["partial_reason"] == f"interrupted while writing {step}"
    assert tum_rows(out / "trajectory.tum") == len(run)
    assert not (out / step).exists() and (out / "trajectory.clf").exists()
    assert hidden(out) == []


# -- Ctrl-C in loop closure's final steps ------------------------------------------------------
@pytest.fixture(scope="module")
def loop_log(tmp_path_factory):
    pytest.importorskip("gtsam", reason="loop closure needs gtsam (pip install 'fuzzypos[graph]')")
    path = tmp_path_factory.mktemp("loop") / "loop.clf"
    return path, write_sim_log(path, laps=1.3, seed=0)


@pytest.mark.parametrize("where", ["optimisation", "realign"])
def test_ctrl_c_in_the_final_optimisation_keeps_the_front_end(
    loop_log, tmp_path, monkeypatch, where
):
    import fuzzypos.graph.outputs as graph_outputs
    from fuzzypos.graph import OnlineMapper

    path, run = loop_log
    if where == "optimisation":
        monkeypatch.setattr(OnlineMapper, "finish", ctrl_c)
    else:  # numba's refine, inside the realignment
        monkeypatch.setattr(graph_outputs, "realign", numba_ctrl_c)
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--loop-closure", "--results", str(out)])
    assert res.exit_code == 130 and "Traceback" not in res.output, res.output
    assert lines_of(res) == [
        (
            "fuzzypos: interrupted in loop closure's final optimisation; the results of the "
            f'{len(run)} scans are kept in {out}/ (summary.json: "partial": true)'
        )
    ]
    s = json.loads((out / "summary.json").read_text())
    assert s["partial_reason"] == "interrupted in loop closure's final optimisation"
    assert "loop closure did not finish: trajectory.tum holds the front end's poses" in s["notes"]
    assert tum_rows(out / "trajectory.tum") == len(run) and (out / "trajectory.clf").exists()
    assert not (out / "graph.g2o").exists() and hidden(out) == []


def test_ctrl_c_while_trajectory_clf_takes_the_optimised_poses(loop_log, tmp_path, monkeypatch):
    """trajectory.clf is written once, at the optimised poses: Ctrl-C on the way leaves no
    stray temporary file; the other files are written."""
    import fuzzypos.io.carmen_write as carmen_write

    path, run = loop_log
    real, calls = carmen_write._held_text, []

    def held_text(held, pose):
        calls.append(1)
        if len(calls) == 10:
            raise KeyboardInterrupt
        return real(held, pose)

    monkeypatch.setattr(carmen_write, "_held_text", held_text)
    out = tmp_path / "res"
    res = runner.invoke(app, ["run", str(path), "--loop-closure", "--results", str(out)])
    assert res.exit_code == 130 and "Traceback" not in res.output, res.output
    s = json.loads((out / "summary.json").read_text())
    assert s["partial_reason"] == "interrupted while writing trajectory.clf"
    assert not (out / "trajectory.clf").exists() and (out / "graph.g2o").exists()
    assert tum_rows(out / "trajectory.tum") == len(run) and hidden(out) == []
