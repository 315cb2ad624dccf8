"""The command line run in-process, and the check every bad-input test makes: exit code 2, one
line on stderr naming what is wrong, no traceback. Importable from every test folder
(``pythonpath = ["tests"]``)."""

from __future__ import annotations

from typer.testing import CliRunner

from pfslam.cli import app

runner = CliRunner()


def invoke(*args):
    """Run ``pfslam ARGS`` in this process: (the result, its stderr)."""
    res = runner.invoke(app, [str(a) for a in args])
    err = res.stderr if hasattr(res, "stderr") else res.output
    return res, err


def one_line_error(res, err, *words):
    """Assert that the run ended with exit code 2 and one line on stderr holding each of
    ``words``, and no traceback; the line."""
    assert res.exit_code == 2, (res.exit_code, res.output, err)
    assert "Traceback" not in res.output and "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]
