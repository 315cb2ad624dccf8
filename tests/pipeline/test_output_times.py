"""Every trajectory pfslam writes has strictly increasing time stamps, true to the log, so
that tools pairing poses by time (evo, ``pfslam evaluate``) pair them as the scans were:
Intel has four scans whose stamp did not increase; written with the previous scan's time,
they made evaluate pair poses with the wrong reference pose (RPE 0.208 m instead of 0.069)."""

import numpy as np
from carmen_sim import write_corrected_log
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.eval.metrics import trajectory_errors
from pfslam.geometry import relative
from pfslam.io.trajectory import read_tum

runner = CliRunner()
N = 80


def _stamps() -> list[str]:
    """Intel-like glitches: repeats, a scan up to 0.86 s back, a swapped pair, at 0.5 s per scan."""
    t = 100.0 + 0.5 * np.arange(N)
    t[10] = t[9]  # repeat
    t[20] = t[19] - 0.86  # back
    t[30], t[31] = t[31], t[30]  # swapped
    t[50] = t[51] = t[49]  # two repeats
    t[70] = t[69] - 0.3
    return [repr(float(x)) for x in t]


def _file_stamps(path):
    return np.array([float(ln.split()[0]) for ln in path.read_text().splitlines() if ln and not ln.startswith("#")])


def test_every_output_trajectory_has_strictly_increasing_stamps_and_pairs_by_scan(tmp_path):
    stamps = _stamps()
    log = tmp_path / "glitchy.log"
    write_corrected_log(log, lambda i: stamps[i], n=N)
    out = tmp_path / "slam"
    res = runner.invoke(app, ["slam", str(log), "--odometry", "synthetic", "-n", "30", "-o", str(out)])
    assert res.exit_code == 0, res.output
    for name in ("trajectory.tum", "odometry.tum", "reference.tum"):
        t = _file_stamps(out / name)
        assert len(t) == N and np.all(np.diff(t) > 0), name
    # Good stamps are written as they are.
    good = [i for i in range(N) if float(stamps[i]) > max(float(s) for s in stamps[:i] or ["-inf"])]
    np.testing.assert_allclose(_file_stamps(out / "trajectory.tum")[good], np.array(stamps, float)[good], atol=1e-9)

    # Pairing by time (what evaluate and evo do) is pairing by scan.
    te, est = read_tum(out / "trajectory.tum")
    tr, ref = read_tum(out / "reference.tum")
    by_time = trajectory_errors(te, est, tr, ref)
    d = by_time.rpe_delta
    err = relative(relative(ref[:-d], ref[d:]), relative(est[:-d], est[d:]))
    by_scan = float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))))
    assert by_time.matched == N
    assert by_time.rpe_trans_rmse == by_scan
    res = runner.invoke(app, ["evaluate", str(out / "trajectory.tum"), "-r", str(out / "reference.tum")])
    assert res.exit_code == 0 and f"{by_scan:.4f}" in res.output, res.output

    # Localization on that map writes strictly increasing stamps too.
    loc = tmp_path / "loc"
    start = [float(v) for v in log.read_text().split("\n", 1)[0].split()[-9:-6]]
    res = runner.invoke(
        app,
        [
            "localize",
            str(log),
            "--odometry",
            "synthetic",
            "--map",
            str(out / "map.yaml"),
            "--initial-pose",
            f"{start[0]},{start[1]},{np.rad2deg(start[2])}",
            "-o",
            str(loc),
        ],
    )
    assert res.exit_code == 0, res.output
    t = _file_stamps(loc / "trajectory.tum")
    assert len(t) == N and np.all(np.diff(t) > 0)
