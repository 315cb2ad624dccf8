"""Writing a run's results: trajectories, map files, pictures, config.yaml and run.json."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from pfslam import __version__
from pfslam.config import CalibrationConfig, dump_sections, to_dict
from pfslam.io.trajectory import write_covariance_csv, write_health_csv, write_tum
from pfslam.pipeline.prepare import MAP_FILE
from pfslam.pipeline.run import JUMP_BREAK, Run, Truth, spread_rose, updated_covariances
from pfslam.process import peak_rss_mb

EARLIER_COLOURS = ("tab:purple", "tab:brown", "tab:olive", "tab:cyan")  # a resumed session's earlier runs

# -- writing the results -----------------------------------------------------------------


def _json(obj: Any) -> Any:
    """JSON-ready copy: NumPy scalars and arrays as Python values, NaN and inf as null."""
    if isinstance(obj, dict):
        return {str(k): _json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _json(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def write_json(path: Path, info: dict[str, Any]) -> None:
    path.write_text(json.dumps(_json(info), indent=2, allow_nan=False))


def write_outputs(
    run: Run,
    out: str | Path,
    input_info: dict[str, Any],
    truth: Truth | None = None,
    truth_label: str = "ground truth",
    calibration: CalibrationConfig | None = None,
) -> Path:
    """Write a run's results into ``out``: trajectory.tum, odometry.tum, config.yaml (the
    filter's settings, and ``calibration``'s when the odometry was calibrated: ready for
    ``--config``), run.json and a picture (SLAM: map.pgm/.yaml and map.png; localization:
    localization.png with particle clouds over the given map, and covariance.csv: the
    estimate's covariance at each update, see :func:`~pfslam.io.trajectory.write_covariance_csv`)."""
    from pfslam.views.figures import both, health_marker, plot_map, run_title, spread_marker

    began = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_tum(out / "trajectory.tum", run.t, run.poses)
    write_tum(out / "odometry.tum", run.t, run.odometry)
    used = (run.config,) if calibration is None else (run.config, calibration)
    (out / "config.yaml").write_text(dump_sections(*used))
    slam = run.kind == "slam"
    name = "SLAM" if slam else "estimate"
    trajs = [("odometry", run.odometry, "tab:orange"), (name, run.poses, "tab:blue")]
    if truth is not None:
        trajs.insert(0, (truth_label, truth[1], "tab:green"))
    if run.resumed is not None:  # the session's earlier runs (by their nodes), each in its colour
        old = run.resumed.session.nodes
        for k in np.unique(old.run):
            colour = EARLIER_COLOURS[int(k) % len(EARLIER_COLOURS)]
            trajs.insert(0, (f"session run {int(k) + 1}", old.poses[old.run == k], colour))
    info: dict[str, Any] = {
        "pfslam_version": __version__,
        "run": run.kind,
        "input": input_info,
        "config": to_dict(run.config),
        **({"calibration_config": to_dict(calibration)} if calibration is not None else {}),
        "scans_processed": run.scans,
        "interrupted": run.interrupted,
        "resamples": run.resamples,
        "updates": run.updates,
        "seconds": run.seconds,
        "scans_per_second": run.scans_per_second,
        "real_time_factor": run.real_time_factor,
        "peak_rss_mb": peak_rss_mb(),
        **({"filter": run.filter_info} if run.filter_info else {}),
        **({"backend": run.backend.as_dict()} if run.backend is not None else {}),
        "metrics": run.metrics,
    }
    states: list[str] = []
    if run.health is not None and run.updated is not None:
        h = run.health
        states = h.state_names()
        write_health_csv(out / "health.csv", run.t, run.updated, h.quality, states, h.explained, h.contradicted)
    if slam:
        from pfslam.backend.graph import write_g2o

        if run.resumed is not None and run.session is not None:  # both sessions' nodes and edges
            write_g2o(out / "graph.g2o", run.session.graph, run.session.nodes.poses)
        elif run.closure is not None:
            write_g2o(out / "graph.g2o", run.closure.graph, run.closure.optimised)
        if run.session is not None:
            from pfslam.pipeline.sessions import write_session

            info["session"] = write_session(out, run, {"pfslam_version": __version__})
        run.grid.save_ros(out / MAP_FILE)
        # The map's name: `pfslam localize --map` starts where this run started (map_run_start).
        info["map"] = f"{MAP_FILE}.yaml"
        title = run_title(run.kind, input_info.get("log"), run.filter_info, run.metrics, name, truth_label)
        # (a resumed run in one colour beside the earlier ones, not coloured by time)
        timed = name if run.resumed is None else None
        marked = health_marker(run.poses[:, :2], states) if states else None
        plot_map(run.grid, out / "map.png", trajs, title=title, times=run.t, timed=timed, extra=marked)
    else:
        info["particles_first_last"] = [int(run.particles[0]), int(run.particles[-1])] if run.scans else None
        write_covariance_csv(out / "covariance.csv", *updated_covariances(run))
        clouds = [(f"particles at {tc - run.t[0]:.0f} s", p) for tc, p in run.clouds]
        # Where the estimate's own uncertainty (the particles' spread) rose, marked under it.
        marks = None
        if run.covariances is not None and len(run.covariances) == len(run.poses):
            cov = run.covariances
            threshold, rose = spread_rose(np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1], 0.0)))
            if threshold is not None and rose.any():
                marks = spread_marker(run.poses[:, :2], rose, threshold)
        plot_map(
            run.grid,
            out / "localization.png",
            trajs,
            title=run_title(run.kind, input_info.get("log"), run.filter_info, run.metrics, name, truth_label),
            clouds=clouds,
            jump=JUMP_BREAK,
            extra=both(marks, health_marker(run.poses[:, :2], states) if states else None),
        )
    if run.error is not None:
        info["error"] = run.error
    if run.phases:
        info["seconds_by_phase"] = {**run.phases, "write": time.perf_counter() - began}
    write_json(out / "run.json", info)
    return out
