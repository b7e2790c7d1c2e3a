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
from fuzzypos.pipeline import Positioner
from fuzzypos.run import run_log
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
