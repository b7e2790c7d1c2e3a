"""Issue 35: inputs that were read wrongly or refused badly. Each test fails without its fix;
bad input is one line ``fuzzypos: error: …`` and exit 2, never a traceback."""

from __future__ import annotations

from typer.testing import CliRunner

from fuzzypos.cli import app
from fuzzypos.io import CarmenReader

runner = CliRunner()


def invoke(args: list[str], code: int) -> list[str]:
    """The non-blank lines of the output, after checking the exit code and no traceback."""
    res = runner.invoke(app, args)
    assert res.exit_code == code, (args, res.output, res.exception)
    assert "Traceback" not in res.output
    return [ln for ln in res.output.splitlines() if ln.strip()]


def one_line_error(args: list[str], *expect: str) -> str:
    lines = invoke(args, 2)
    assert len(lines) == 1 and lines[0].startswith("fuzzypos: error: "), lines
    for text in expect:
        assert text in lines[0], (text, lines[0])
    return lines[0]


def flaser(ranges, odom, t: float) -> str:
    r = " ".join(str(v) for v in ranges)
    ox, oy, ot = odom
    return f"FLASER {len(ranges)} {r} {ox} {oy} {ot} {ox} {oy} {ot} {t!r} host {t!r}\n"


def small_log(path, n: int = 5, *, stamps=None) -> str:
    """``n`` 3-beam scans, the odometry moving 0.1 m a scan, 0.1 s apart."""
    stamps = [0.1 * k for k in range(n)] if stamps is None else stamps
    text = "".join(flaser([1.0, 2.0, 3.0], (0.1 * k, 0, 0), t) for k, t in enumerate(stamps))
    path.write_text(text)
    return text


# -- 1. a byte order mark ---------------------------------------------------------------------
def test_a_byte_order_mark_keeps_the_first_scan(tmp_path):
    path = tmp_path / "bom.clf"
    text = small_log(path, 4)
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    reader = CarmenReader(path)
    stamps = [rec.scan.stamp for rec in reader.records()]
    assert stamps == [0.0, 0.1, 0.2, 0.30000000000000004] and reader.bad_lines == 0
    assert len(reader.scan_stamps()) == 4
