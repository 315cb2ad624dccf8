"""`pfslam evaluate`: what the relations metric matched and skipped (and why), and an RPE
step longer than the trajectory said in one warning instead of lowered silently."""

import numpy as np
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.io.trajectory import write_tum

runner = CliRunner()


def _stderr(res):
    return res.stderr if hasattr(res, "stderr") else res.output


def _line(tmp_path, n=20):
    t = np.arange(n) * 0.5
    poses = np.column_stack([t * 0.3, np.zeros(n), np.zeros(n)])
    write_tum(tmp_path / "est.tum", t, poses)
    return t


def test_relations_report_what_was_skipped_and_why(tmp_path):
    t = _line(tmp_path)
    (tmp_path / "r.rel").write_text(
        f"{100 + t[2]} {100 + t[6]} 0.6 0 0 0 0 0\n"  # matched
        f"{100 + t[3]} {100 + t[3] + 0.004} 0.001 0 0 0 0 0\n"  # both ends on pose 3
        f"{100 + t[4]} {100 + 55.0} 1 0 0 0 0 0\n"  # no pose at its second end
    )
    res = runner.invoke(
        app, ["evaluate", str(tmp_path / "est.tum"), "--relations", str(tmp_path / "r.rel"), "--time-offset", "100"]
    )
    assert res.exit_code == 0, res.output
    assert (
        "relations: 1 matched, 2 skipped (1 with an end not within 0.02 s of an estimated pose, "
        "1 with both ends on the same pose)"
    ) in res.stdout
    assert "translation 0.0000" in res.stdout


def test_no_relation_on_two_poses_is_one_line_naming_the_reasons(tmp_path):
    t = _line(tmp_path)
    (tmp_path / "r.rel").write_text(f"{100 + t[3]} {100 + t[3] + 0.004} 0.001 0 0 0 0 0\n")
    res = runner.invoke(
        app, ["evaluate", str(tmp_path / "est.tum"), "--relations", str(tmp_path / "r.rel"), "--time-offset", "100"]
    )
    assert res.exit_code == 2
    lines = [ln for ln in _stderr(res).splitlines() if ln.strip()]
    assert len(lines) == 1 and "r.rel" in lines[0] and "1 with both ends on the same pose" in lines[0], lines


def test_an_rpe_delta_longer_than_the_trajectory_is_said(tmp_path):
    _line(tmp_path, n=8)
    est = str(tmp_path / "est.tum")
    res = runner.invoke(app, ["evaluate", est, "-r", est, "--rpe-delta", "50"])
    assert res.exit_code == 0, res.output
    warnings = [ln for ln in _stderr(res).splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "--rpe-delta 50" in warnings[0] and "over 7 poses" in warnings[0], warnings
    res = runner.invoke(app, ["evaluate", est, "-r", est, "--rpe-delta", "3"])
    assert res.exit_code == 0 and "warning" not in _stderr(res)


def test_plot_writes_the_error_pictures_and_needs_a_reference(tmp_path):
    t = _line(tmp_path, n=40)
    ref = np.column_stack([t * 0.3, 0.02 * np.sin(t), np.zeros(len(t))])
    write_tum(tmp_path / "ref.tum", t, ref)
    res = runner.invoke(
        app, ["evaluate", str(tmp_path / "est.tum"), "-r", str(tmp_path / "ref.tum"), "--plot", str(tmp_path / "pics")]
    )
    assert res.exit_code == 0, res.output
    assert "trajectory_error.png" in res.output and "error_over_time.png" in res.output
    assert sorted(p.name for p in (tmp_path / "pics").iterdir()) == ["error_over_time.png", "trajectory_error.png"]
    (tmp_path / "r.rel").write_text(f"{t[2]} {t[6]} 1.2 0 0 0 0 0\n")
    res = runner.invoke(
        app,
        [
            "evaluate",
            str(tmp_path / "est.tum"),
            "--relations",
            str(tmp_path / "r.rel"),
            "--plot",
            str(tmp_path / "pics2"),
        ],
    )
    assert res.exit_code == 2
    err = [ln for ln in _stderr(res).splitlines() if ln.strip()]
    assert len(err) == 1 and "--plot" in err[0] and "reference" in err[0]
    assert not (tmp_path / "pics2").exists()
