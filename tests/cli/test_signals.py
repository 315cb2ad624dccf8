"""How the program ends when it is told to stop or cannot write: SIGTERM (batch schedulers,
`timeout`) keeps the results like Ctrl-C and exits with 143; a standard output that cannot be
written is one line and exit code 2, a closed pipe a quiet exit (141)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pfslam import cli


def _pfslam(*args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "pfslam.cli", *map(str, args)], **kwargs)


@pytest.mark.slow
def test_sigterm_during_a_run_writes_the_results_and_exits_143(office_sim, short_office, tmp_path):
    from typer.testing import CliRunner

    # The same SLAM on a short log first, in this process: Numba's kernels are compiled and
    # cached then, so the child below is in its run loop soon after it has loaded the log.
    warm = CliRunner().invoke(
        cli.app, ["slam", str(short_office.lidar_path), "--level-head", "-o", str(tmp_path / "warm")]
    )
    assert warm.exit_code == 0, warm.output
    out = tmp_path / "out"
    # With --level-head (no --joint) the loader warns (head level) right after loading: the run starts then.
    p = _pfslam(
        "slam",
        office_sim.lidar_path,
        "--level-head",
        "-o",
        out,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PFSLAM_PROGRESS": "1"},
    )
    try:
        first = p.stderr.readline()
        assert "no joint file given" in first, first
        time.sleep(1.5)  # well into the 7,200 scans
        assert p.poll() is None, "the run ended before the signal"
        p.send_signal(signal.SIGTERM)
        rest, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
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
    from pfslam.pipeline import Outcome, Scores, interrupts_held

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
