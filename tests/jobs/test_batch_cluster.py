"""``fuzzypos batch --address``: joining a Ray head started by ``ray start --head`` (stopped at
the end)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuzzypos.cli import app
from helpers import write_sim_log


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ready(log: Path, proc: subprocess.Popen[bytes], seconds: float) -> bool:
    """Whether ``ray start --block`` says it is up (blocking) within ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end and proc.poll() is None:
        if "will now block" in log.read_text(errors="replace"):
            return True
        time.sleep(0.5)
    return False


@pytest.fixture(scope="module")
def head(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A head on 127.0.0.1 (``ray start --head --block``, token authentication off on this
    loopback test cluster); stopped by terminating that process, which stops its own."""
    ray = pytest.importorskip("ray", reason="Ray (the ray extra) is not installed")
    exe = shutil.which("ray", path=os.path.dirname(sys.executable)) or shutil.which("ray")
    if exe is None or ray.is_initialized():
        pytest.skip("no ray command (or Ray already up in this process)")
    port = _free_port()
    saved = {k: os.environ.get(k) for k in ("RAY_USAGE_STATS_ENABLED", "RAY_AUTH_MODE")}
    os.environ.update(RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="disabled")
    start = [exe, "start", "--head", f"--port={port}", "--node-ip-address=127.0.0.1", "--block"]
    start += ["--num-cpus=2", "--include-dashboard=false", "--disable-usage-stats"]
    log = tmp_path_factory.mktemp("head") / "head.log"
    with open(log, "wb") as f:
        proc = subprocess.Popen(start, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        if not _ready(log, proc, 90):
            pytest.skip(f"ray start --head did not come up: {log.read_text()[-300:]}")
        yield f"127.0.0.1:{port}"
    finally:
        if ray.is_initialized():
            ray.shutdown()
        proc.terminate()  # the head stops what it started
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:  # pragma: no cover
            os.killpg(proc.pid, signal.SIGKILL)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def test_batch_joins_a_head(head: str, tmp_path: Path) -> None:
    write_sim_log(tmp_path / "one.clf", laps=0.05)
    out = tmp_path / "out"
    args = ["batch", str(tmp_path / "one.clf"), "--out", str(out), "--max-scans", "5"]
    res = CliRunner().invoke(app, [*args, "--address", head])
    assert res.exit_code == 0, res.output
    (row,) = json.loads((out / "batch.json").read_text())["rows"]
    assert row["status"] == "ok" and row["scans"] == 5
    assert (out / "one.clf" / "default" / "trajectory.tum").is_file()
