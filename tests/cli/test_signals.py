"""How the program ends when it is told to stop or cannot write: SIGTERM (batch schedulers,
`timeout`) keeps the results like Ctrl-C and exits with 143; a standard output that cannot be
written is one line and exit code 2, a closed pipe a quiet exit (141)."""

import json
import os
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from pfslam import cli


def _pfslam(*args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "pfslam.cli", *map(str, args)], **kwargs)


# Rich's cursor moves and colours, stripped from what a pseudo-terminal received.
_ANSI = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]")


def _read_terminal(master: int, done: Callable[[str], bool] | None, timeout: float) -> str:
    """What the child wrote to its terminal (``master``: our end of it), without the escape
    codes: read until ``done(text)`` holds, or until the child has closed the terminal (it
    ended) when ``done`` is None. Fails after ``timeout`` seconds: a guard against a hang, not
    a speed check."""
    raw, deadline = b"", time.monotonic() + timeout
    while True:
        text = _ANSI.sub("", raw.decode(errors="replace"))
        if done is not None and done(text):
            return text
        left = deadline - time.monotonic()
        assert left > 0, f"nothing awaited on the terminal after {timeout} s: {text[-2000:]}"
        if not select.select([master], [], [], min(left, 1.0))[0]:
            continue
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: every end of the terminal on the child's side is closed
            chunk = b""
        if not chunk:
            assert done is None, f"the run ended before what was awaited: {text[-2000:]}"
            return text
        raw += chunk


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "openpty"), reason="no pseudo-terminals on this system")
def test_sigterm_during_a_run_writes_the_results_and_exits_143(office_sim, tmp_path):
    out = tmp_path / "out"
    # Its standard error is a (pseudo-)terminal, as when a person runs it: the progress bar is
    # drawn as the run goes, and the signal is sent once it shows scans done, not after a guess
    # at how long loading takes or how fast the scans go.
    master, slave = os.openpty()
    try:
        with open(tmp_path / "stdout.txt", "w") as stdout:
            p = _pfslam(
                "slam",
                office_sim.lidar_path,
                "--level-head",
                "-o",
                out,
                stdout=stdout,
                stderr=slave,
                env={**os.environ, "COLUMNS": "200"},
            )
    finally:
        os.close(slave)  # the child has its own: the terminal closes when the child ends

    def scans_done(text: str) -> bool:
        return any(int(n) > 0 for n in re.findall(r"\bSLAM\b[^\r\n]*?(\d+)/7200\b", text))

    try:
        _read_terminal(master, scans_done, timeout=600)
        assert p.poll() is None, "the run ended before the signal"
        p.send_signal(signal.SIGTERM)
        err = _read_terminal(master, None, timeout=300)
        p.wait(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        os.close(master)
    assert p.returncode == 143, (p.returncode, err)
    assert "Traceback" not in err and "interrupted: results for the" in err, err
    for name in ("trajectory.tum", "map.pgm", "map.yaml", "odometry.tum", "config.yaml"):
        assert (out / name).is_file(), name
    info = json.loads((out / "run.json").read_text())
    assert info["interrupted"] is True and 0 < info["scans_processed"] < 7200, info["scans_processed"]


def test_sigterm_while_the_results_are_written_is_held():
    """Like Ctrl-C, a SIGTERM while the results are written waits until they are (noted, not
    raised), and the command line's exit code then says SIGTERM (143)."""
    import typer

    from pfslam.cli.app import received_signals
    from pfslam.cli.render import report as _report
    from pfslam.pipeline import Outcome, Scores
    from pfslam.process import interrupts_held

    received = received_signals()
    saved = list(received)
    received.clear()
    try:
        before = signal.getsignal(signal.SIGTERM)
        with interrupts_held() as got:
            os.kill(os.getpid(), signal.SIGTERM)
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handlers run between bytecodes
        assert got == [signal.SIGTERM, signal.SIGINT]
        assert signal.getsignal(signal.SIGTERM) is before

        class _Run:
            error, interrupted, scans = None, True, 3

        with pytest.raises(typer.Exit) as stop:
            _report(Outcome(_Run(), Scores(), Path("out"), "log", got))  # type: ignore[arg-type]
        assert stop.value.exit_code == 130 and signal.SIGTERM in received
    finally:
        received[:] = saved


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_standard_output_is_one_line_and_exit_2():
    commands = [["dump-config"], ["dump-config", "slam"], ["version"], ["--help"]]
    with open("/dev/full", "w") as full:  # the four at once: each takes seconds to start
        procs = [_pfslam(*args, stdout=full, stderr=subprocess.PIPE, text=True) for args in commands]
        results = [(args, p.communicate(timeout=120)[1], p.returncode) for args, p in zip(commands, procs)]
    for args, err, code in results:
        assert code == 2, (args, code, err)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert lines == ["error: standard output: No space left on device"], (args, err)


def test_a_closed_pipe_is_a_quiet_exit():
    p = _pfslam("dump-config", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # the reader went away (`pfslam dump-config | head -0`) before anything was written
    err = p.stderr.read().decode()
    p.wait(timeout=120)
    assert p.returncode == cli.EXIT_CLOSED_PIPE, (p.returncode, err)
    assert err.strip() == "", err
