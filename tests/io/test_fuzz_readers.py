"""Fuzzing every reader with damaged copies of small valid files: CARMEN logs (plain and gzip),
ROS1 bags, ROS2 bags (sqlite3, mcap), TUM trajectories, relations files, TOML configs.

Each example is a valid seed file mutated by hypothesis (truncation, byte flips and
overwrites, gzip corruption, lines deleted, doubled or inserted from random text). The library
call may succeed or raise its own typed error (:class:`~fuzzypos.io.LogFormatError`,
:class:`~fuzzypos.config.ConfigError`), nothing else; a few examples also go through the
command line (``fuzzypos info`` / ``evaluate``), which must exit 0 or 2 with a one-line error
and no traceback. The budgets are bounded (the whole file runs in seconds)."""

from __future__ import annotations

import contextlib
import gzip
import math
import shutil
import warnings
from collections.abc import Callable
from itertools import count
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.config import Config, ConfigError
from fuzzypos.io import (
    BagReader,
    CarmenReader,
    LogFormatError,
    describe_log,
    open_log,
    read_relations,
    read_tum,
    write_tum,
)
from helpers import make_bag, standard, write_relations, write_sim_log

runner = CliRunner()

#: a small CARMEN log with every message type the reader interprets
CARMEN_TEXT = "\n".join(
    [
        "# a small CARMEN log",
        "PARAM robot_frontlaser_offset 0.1",
        "PARAM robot_front_laser_max 30.0",
        "PARAM some_other_param 1",
        "ODOM 0.0 0.0 0.0 0 0 0 0.95 host 0.95",
        "FLASER 5 1.0 1.1 1.2 30.0 1.4 0 0 0 0.0 0.0 0.0 1.0 host 1.0",
        "TRUEPOS 0 0 0 0 0 0 1.0 host 1.0",
        "ODOM 0.1 0.0 0.01 0 0 0 1.05 host 1.05",
        (
            "ROBOTLASER1 0 -1.5 3.0 0.75 20.0 0.01 0 5 1.0 1.1 1.2 1.3 1.4 2 7 8 "
            "0.1 0 0.01 0.1 0 0.01 0 0 0 0 0 1.1 host 1.1"
        ),
        "SYNC 1.15 host 1.15",
        "FLASER 5 1.0 1.1 1.2 1.3 1.4 0.1 0 0.01 0.2 0 0.02 1.2 host 1.2",
        "ODOM 0.2 0.0 0.02 0 0 0 1.25 host 1.25",
        "",
    ]
)

#: bits of lines for the random text lines inserted into text files
_WORDS = st.sampled_from(
    ["FLASER", "ROBOTLASER1", "ODOM", "TRUEPOS", "PARAM", "robot_front_laser_max",
     "robot_frontlaser_offset", "#", "0", "1", "2", "5", "-1", "180", "0.5", "-0.0", "nan",
     "inf", "-inf", "1e309", "1e-320", "1" * 400, "0x1f", "x", "é", "\x00", "\t"]
)  # fmt: skip
_NUMBER = st.floats(allow_nan=True, allow_infinity=True).map(repr)
_LINE = st.lists(st.one_of(_WORDS, _NUMBER), max_size=30).map(" ".join)


@st.composite
def mutated(draw: st.DrawFn, seed: bytes, text: bool) -> bytes:
    """``seed`` damaged by one to four operations (``text``: line operations too)."""
    data = bytearray(seed)
    ops = ["truncate", "flip", "overwrite"] + (["insert", "delete", "double"] if text else [])
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(ops))
        if not data and op != "insert":
            continue
        if op == "truncate":
            del data[draw(st.integers(0, len(data) - 1)) :]
        elif op == "flip":
            i = draw(st.integers(0, len(data) - 1))
            data[i] ^= 1 << draw(st.integers(0, 7))
        elif op == "overwrite":
            i = draw(st.integers(0, len(data) - 1))
            chunk = draw(st.binary(min_size=1, max_size=8))
            data[i : i + len(chunk)] = chunk
        else:
            lines = bytes(data).split(b"\n")
            k = draw(st.integers(0, len(lines) - 1))
            if op == "insert":
                lines.insert(k, draw(_LINE).encode("utf-8", "surrogatepass"))
            elif op == "delete":
                del lines[k]
            else:
                lines.insert(k, lines[k])
            data = bytearray(b"\n".join(lines))
    return bytes(data)


@st.composite
def damaged(draw: st.DrawFn, plain: bytes) -> bytes:
    """A damaged text file: its text mutated (plain or gzipped afterwards), or the gzip stream
    of the intact text mutated (corruption, truncation)."""
    how = draw(st.sampled_from(["text", "text-gz", "gz"]))
    if how == "gz":
        return draw(mutated(gzip.compress(plain, mtime=0), text=False))
    data = draw(mutated(plain, text=True))
    return gzip.compress(data, mtime=0) if how == "text-gz" else data


_FUZZ = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
_CLI = settings(_FUZZ, max_examples=12)

_names = count()


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The valid seed files, each checked to read as what it is."""
    d = tmp_path_factory.mktemp("seeds")
    out = {"carmen": d / "small.clf", "sim": d / "sim.clf"}
    out["carmen"].write_text(CARMEN_TEXT)
    assert len(list(CarmenReader(out["carmen"]).records())) == 3
    run = write_sim_log(out["sim"], laps=0.03)
    assert len(list(CarmenReader(out["sim"]).records())) == len(run)
    out["tum"] = d / "traj.tum"
    stamps = np.array([1.0, 1.5, 2.25, 3.0])
    poses = np.array([[0, 0, 0], [0.5, 0.1, 0.2], [1.0, 0.3, -3.1], [1.5, 0.2, 3.0]])
    write_tum(out["tum"], stamps, poses, header_comment="a trajectory")
    assert read_tum(out["tum"])[1].shape == (4, 3)
    out["relations"] = d / "log.relations"
    write_relations(out["relations"], stamps, poses, [(0, 1), (1, 2), (0, 3), (3, 2)])
    assert len(read_relations(out["relations"])) == 4
    out["toml"] = d / "config.toml"
    out["toml"].write_text(Config.preset("paper").to_toml())
    assert Config.from_toml(out["toml"]) == Config.preset("paper")
    for kind in ("ros1", "ros2-sqlite3", "ros2-mcap"):
        sub = d / kind
        sub.mkdir()
        out[kind] = make_bag(sub, kind, standard)
        assert len(list(BagReader(out[kind]).records())) > 0
    return out


def _fresh(tmp: Path, name: str) -> Path:
    return tmp / f"{next(_names)}-{name}"


def _only_typed(call: Callable[[], object], allowed: tuple[type[BaseException], ...]) -> None:
    """Run ``call``: success, a warning, or one of ``allowed``; anything else fails the test."""
    with warnings.catch_warnings(), contextlib.suppress(*allowed):
        warnings.simplefilter("ignore")
        call()


def _read_log(path: Path, **options: object) -> None:
    """Read a log through every path the library offers: its reader, open_log, describe_log,
    the stamp check."""
    log = open_log(path, **options)  # type: ignore[arg-type]
    for _ in log.records():
        pass
    describe_log(log)
    log.check_stamps()
    log.scan_count_hint()


def _cli_ok(args: list[str]) -> None:
    """The command line exits 0, or 2 with one ``fuzzypos: error:`` line (warnings aside)."""
    res = runner.invoke(app, args)
    assert "Traceback" not in res.output, res.output
    assert res.exit_code in (0, 2), (res.exit_code, res.output, res.exception)
    if res.exit_code == 2:
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        errors = [ln for ln in lines if ln.startswith("fuzzypos: error: ")]
        rest = [ln for ln in lines if not ln.startswith(("fuzzypos: error: ", "fuzzypos: warn"))]
        assert len(errors) == 1 and not rest, res.output


# -- CARMEN ------------------------------------------------------------------------------------
_CARMEN_OPTIONS = st.fixed_dictionaries(
    {},
    optional={
        "skip_bad_lines": st.booleans(),
        "odometry": st.sampled_from(["scan", "interpolated"]),
        "max_range": st.sampled_from([None, 5.0, math.inf]),
    },
)


@_FUZZ
@given(data=st.data())
def test_carmen_reader_raises_only_its_errors(seeds, tmp_path, data):
    seed = seeds[data.draw(st.sampled_from(["carmen", "sim"]))]
    path = _fresh(tmp_path, "log.clf")
    path.write_bytes(data.draw(damaged(seed.read_bytes())))
    options = data.draw(_CARMEN_OPTIONS)
    _only_typed(lambda: list(CarmenReader(path, **options)), (LogFormatError,))
    _only_typed(lambda: _read_log(path, **options), (LogFormatError,))


@_CLI
@given(data=st.data())
def test_info_on_a_damaged_carmen_log(seeds, tmp_path, data):
    path = _fresh(tmp_path, "log.clf")
    path.write_bytes(data.draw(damaged(seeds["carmen"].read_bytes())))
    _cli_ok(["info", str(path)])


# -- bags --------------------------------------------------------------------------------------
def _damaged_bag(seed: Path, target: Path, data: st.DataObject) -> Path:
    """A copy of the bag (a ROS1 file, or a ROS2 directory one of whose files is damaged)."""
    if seed.is_file():
        target.write_bytes(data.draw(mutated(seed.read_bytes(), text=False)))
        return target
    shutil.copytree(seed, target)
    victim = data.draw(st.sampled_from(sorted(target.iterdir())))
    text = victim.name == "metadata.yaml"
    victim.write_bytes(data.draw(mutated(victim.read_bytes(), text=text)))
    return target


@settings(_FUZZ, max_examples=40)
@given(data=st.data(), kind=st.sampled_from(["ros1", "ros2-sqlite3", "ros2-mcap"]))
def test_bag_reader_raises_only_its_errors(seeds, tmp_path, data, kind):
    path = _damaged_bag(seeds[kind], _fresh(tmp_path, "bag"), data)
    _only_typed(lambda: list(BagReader(path)), (LogFormatError,))
    _only_typed(lambda: _read_log(path), (LogFormatError,))


@_CLI
@given(data=st.data(), kind=st.sampled_from(["ros1", "ros2-sqlite3", "ros2-mcap"]))
def test_info_on_a_damaged_bag(seeds, tmp_path, data, kind):
    path = _damaged_bag(seeds[kind], _fresh(tmp_path, "bag"), data)
    _cli_ok(["info", str(path)])


# -- TUM and relations -------------------------------------------------------------------------
@_FUZZ
@given(data=st.data())
def test_tum_and_relations_readers_raise_only_their_errors(seeds, tmp_path, data):
    for name, read in (("tum", read_tum), ("relations", read_relations)):
        path = _fresh(tmp_path, name)
        path.write_bytes(data.draw(damaged(seeds[name].read_bytes())))
        _only_typed(lambda p=path, r=read: r(p), (LogFormatError,))


@_CLI
@given(data=st.data())
def test_evaluate_with_a_damaged_trajectory_or_relations(seeds, tmp_path, data):
    tum, rel = _fresh(tmp_path, "traj.tum"), _fresh(tmp_path, "log.relations")
    tum.write_bytes(data.draw(damaged(seeds["tum"].read_bytes())))
    rel.write_bytes(data.draw(damaged(seeds["relations"].read_bytes())))
    _cli_ok(["evaluate", str(tum), "--relations", str(seeds["relations"])])
    _cli_ok(["evaluate", str(seeds["tum"]), "--relations", str(rel)])


# -- TOML configs ------------------------------------------------------------------------------
_TOML_LINE = st.one_of(
    _LINE,
    st.builds(
        "{} = {}".format,
        st.sampled_from(["preset", "max_speed", "range_max", "no_return_bands", "iterations"]),
        st.one_of(_WORDS, _NUMBER, st.just("[[1, 2], [3]]"), st.just('"x"'), st.just("[")),
    ),
    st.sampled_from(["[odometry]", "[scanner]", "[nope]", "[[scanner]]", "x = 1" * 3]),
)


@_FUZZ
@given(data=st.data())
def test_config_loader_raises_only_config_errors(seeds, tmp_path, data):
    path = _fresh(tmp_path, "config.toml")
    text = seeds["toml"].read_bytes()
    if data.draw(st.booleans()):  # a line of TOML-ish text somewhere
        lines = text.split(b"\n")
        lines.insert(data.draw(st.integers(0, len(lines))), data.draw(_TOML_LINE).encode())
        text = b"\n".join(lines)
    path.write_bytes(data.draw(mutated(text, text=True)))
    _only_typed(lambda: Config.from_toml(path), (ConfigError,))


@_CLI
@given(data=st.data())
def test_info_with_a_damaged_config(seeds, tmp_path, data):
    path = _fresh(tmp_path, "config.toml")
    path.write_bytes(data.draw(mutated(seeds["toml"].read_bytes(), text=True)))
    _cli_ok(["info", str(seeds["carmen"]), "--config", str(path)])
