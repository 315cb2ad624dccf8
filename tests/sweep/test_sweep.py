"""`pfslam sweep`: spec parsing and validation, a small grid on a local Dask cluster whose
figures are those of `pfslam slam` run by hand, failed / killed / timed-out runs, resuming,
and an existing cluster reached with --scheduler."""

import contextlib
import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.errors import InputError
from pfslam.sweep import columns as sweep_columns
from pfslam.sweep import jobs as sweep_jobs
from pfslam.sweep import runner as sweep_runner
from pfslam.sweep import spec as sweep_spec
from pfslam.sweep import table as sweep_table

runner = CliRunner()


@pytest.fixture(scope="module")
def sim(short_office):
    """The 10 s (400 scans) simulated THOR office log the command-line tests run (lidar, joint,
    ground truth): what a sweep does with its runs does not need a longer one. Read-only."""
    return short_office


def _write_spec(folder: Path, spec: dict) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "spec.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def _sim_log(sim, name="sim") -> dict:
    return {
        "name": name,
        "path": str(sim.lidar_path),
        "joint": str(sim.joint_path),
        "ground_truth": str(sim.groundtruth_path),
    }


# -- the spec ------------------------------------------------------------------------------


def test_lists_and_ranges_expand_to_the_grid(tmp_path):
    for name in ("a.log", "b.log"):
        (tmp_path / name).write_text("x")
    spec = sweep_spec.parse_spec(
        {
            "logs": [{"name": "a", "path": "a.log"}, {"name": "b", "path": "b.log", "odometry": "synthetic:{seed}"}],
            "seeds": {"from": 0, "to": 4},
            "settings": {
                "particles": [20, 40],
                "motion.axle": {"from": 1, "to": 2, "step": 0.5},
                "local_search.enabled": [False, True],
            },
        },
        tmp_path / "spec.yaml",
    )
    assert spec.seeds == (0, 1, 2, 3, 4)
    assert spec.settings == {
        "particles": (20, 40),
        "motion.axle": (1.0, 1.5, 2.0),
        "local_search.enabled": (False, True),
    }
    assert spec.logs[0].path == tmp_path / "a.log"  # relative to the spec's folder
    jobs = sweep_jobs.make_jobs(spec, tmp_path / "out")
    assert len(jobs) == spec.runs == 2 * 2 * 3 * 2 * 5
    assert len({j.run_dir for j in jobs}) == len(jobs) == len({j.fingerprint for j in jobs})
    combos = {(j.settings["particles"], j.settings["motion.axle"], j.settings["local_search.enabled"]) for j in jobs}
    assert len(combos) == 12 and (40, 1.5, True) in combos
    first = jobs[0]
    assert first.run_dir == "runs/a/particles=20,motion.axle=1.0,local_search.enabled=false/seed0"
    # A float range lands on its end points despite rounding; an integer range stays integer.
    assert sweep_spec.expand_range(tmp_path, "k", {"from": 0.1, "to": 0.3, "step": 0.1}) == [0.1, 0.2, 0.3]
    assert sweep_spec.expand_range(tmp_path, "k", {"from": 50, "to": 150, "step": 50}) == [50, 100, 150]


def test_seed_placeholder_becomes_each_runs_seed(tmp_path):
    (tmp_path / "c.log").write_text("x")
    spec = sweep_spec.parse_spec(
        {
            "logs": [{"name": "c", "path": "c.log", "odometry": "synthetic:{seed}", "args": ["--calibrate"]}],
            "seeds": [3, 7],
        },
        tmp_path / "s.yaml",
    )
    jobs = sweep_jobs.make_jobs(spec, tmp_path / "out")
    assert [j.odometry for j in jobs] == ["synthetic:3", "synthetic:7"]
    cmd = jobs[1].command()
    assert cmd[cmd.index("--odometry") + 1] == "synthetic:7" and cmd[cmd.index("--seed") + 1] == "7"
    assert cmd[-1] == "--calibrate" and jobs[1].run_dir == "runs/c/default/seed7"


def test_a_ros2_bag_folder_is_a_log_and_its_topics_go_in_args(tmp_path):
    bag = tmp_path / "walk_bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    spec = sweep_spec.parse_spec(
        {"logs": [{"name": "walk", "path": "walk_bag", "args": ["--scan-topic", "/scan"]}], "seeds": [1]},
        tmp_path / "s.yaml",
    )
    cmd = sweep_jobs.make_jobs(spec, tmp_path / "out")[0].command()
    assert str(bag) in cmd and cmd[-2:] == ["--scan-topic", "/scan"]
    (tmp_path / "plain").mkdir()  # a folder that is no bag is still refused, saying why
    with pytest.raises(InputError, match="is a folder, not a log file or a ROS 2 bag"):
        sweep_spec.parse_spec({"logs": [{"name": "p", "path": "plain"}], "seeds": [1]}, tmp_path / "s.yaml")


@pytest.mark.parametrize(
    "change, key, words",
    [
        ({"runs": 3}, "runs", "unknown key"),
        ({"logs": [{"name": "a", "path": "a.log", "jiont": "x"}]}, "logs[0].jiont", "unknown key"),
        ({"logs": [{"name": "a", "path": "missing.log"}]}, "logs[0] (a).path", "log file not found"),
        ({"settings": {"particles": [20, -1]}}, "settings.particles", "particles must be an integer in 0.."),
        ({"settings": {"sensor.nope": [1]}}, "settings.sensor.nope", "unknown config key 'sensor.nope'"),
        ({"settings": {"seed": [1, 2]}}, "settings.seed", "comes from 'seeds'"),
        ({"settings": {"sensor.temperature": {"from": 1, "to": 0}}}, "settings.sensor.temperature", "below"),
        ({"seeds": [0, -1]}, "seeds", "non-negative integer"),
        ({"logs": [{"name": "a", "path": "a.log", "odometry": "synthetic:{sed}"}]}, "logs[0] (a).odometry", "seed"),
        ({"logs": [{"name": "a", "path": "a.log", "args": ["--seed", "3"]}]}, "logs[0] (a).args", "set by the sweep"),
    ],
)
def test_a_bad_spec_is_one_line_naming_the_spec_and_the_key(tmp_path, change, key, words):
    (tmp_path / "a.log").write_text("x")
    _one_line_spec_error(tmp_path, {"logs": [{"name": "a", "path": "a.log"}], "seeds": [0], **change}, key, words)


def _one_line_spec_error(folder, spec, key, words):
    """Loading ``spec`` (written into ``folder``) fails with one line: the spec file, the key, ``words``."""
    path = _write_spec(folder, spec)
    with pytest.raises(InputError) as e:
        sweep_spec.load_spec(path)
    text = str(e.value)
    assert text.startswith(f"{path}: {key}: ") and words in text and "\n" not in text, text


def test_the_command_rejects_a_bad_spec_with_exit_2_before_running_anything(tmp_path):
    (tmp_path / "a.log").write_text("x")
    path = _write_spec(tmp_path, {"logs": [{"name": "a", "path": "a.log"}], "settings": {"particles": ["many"]}})
    res = runner.invoke(app, ["sweep", str(path), "-o", str(tmp_path / "out")])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "settings.particles" in lines[0] and str(path) in lines[0], res.output
    assert not (tmp_path / "out").exists()


def test_resume_plan_skips_done_runs_and_retries_failed_ones_on_request(tmp_path):
    (tmp_path / "a.log").write_text("x")
    spec = sweep_spec.parse_spec({"logs": [{"name": "a", "path": "a.log"}], "seeds": [0, 1, 2]}, tmp_path / "s.yaml")
    jobs = sweep_jobs.make_jobs(spec, tmp_path / "out")
    for job, status in zip(jobs[:2], ("ok", "killed")):
        job.folder.mkdir(parents=True)
        sweep_runner.write_row(job, sweep_runner.failed_row(job, status, ""))
    done, todo = sweep_runner.plan(jobs)
    assert set(done) == {jobs[0].run_dir, jobs[1].run_dir} and todo == [jobs[2]]
    done, todo = sweep_runner.plan(jobs, retry_failed=True)
    assert set(done) == {jobs[0].run_dir} and todo == jobs[1:]
    # A row of another job (the spec changed under the same names) is not this run's.
    other = sweep_jobs.make_jobs(
        sweep_spec.parse_spec(
            {"logs": [{"name": "a", "path": "a.log", "args": ["--every", "2"]}], "seeds": [0]}, tmp_path / "s.yaml"
        ),
        tmp_path / "out",
    )
    assert sweep_runner.plan(other) == ({}, other)


# -- runs ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def grid(sim, tmp_path_factory):
    """A 2 seeds × 2 settings sweep of the simulated log on 2 local workers."""
    folder = tmp_path_factory.mktemp("grid")
    spec = _write_spec(folder, {"logs": [_sim_log(sim)], "seeds": [0, 1], "settings": {"particles": [20, 40]}})
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(folder / "out"), "--workers", "2"])
    return folder / "out", res


@pytest.mark.slow
def test_a_small_grid_gives_the_figures_of_pfslam_slam_run_by_hand(grid, sim, tmp_path):
    out, res = grid
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out / "results.parquet")
    csv = pd.read_csv(out / "results.csv")
    assert len(df) == len(csv) == 4 and (df["status"] == "ok").all()
    assert list(df.columns[:4]) == ["log", "seed", "particles", "status"]
    assert sorted(zip(df["particles"], df["seed"])) == [(20, 0), (20, 1), (40, 0), (40, 1)]
    assert (out / "summary.png").stat().st_size > 10_000
    assert (df["peak_rss_mb"] > 20).all() and (df["scans"] == 400).all() and df["ate_aligned"].notna().all()
    for particles, seed in ((40, 1), (20, 0)):
        by_hand = tmp_path / f"hand{particles}_{seed}"
        r = runner.invoke(
            app,
            [
                "slam",
                str(sim.lidar_path),
                "-j",
                str(sim.joint_path),
                "-g",
                str(sim.groundtruth_path),
                "--particles",
                str(particles),
                "--seed",
                str(seed),
                "-o",
                str(by_hand),
            ],
        )
        assert r.exit_code == 0, r.output
        slam = json.loads((by_hand / "run.json").read_text())["metrics"]["SLAM"]
        row = df[(df["particles"] == particles) & (df["seed"] == seed)].iloc[0]
        assert row["ate_aligned"] == slam["ate_rmse_aligned"] and row["ate_raw"] == slam["ate_rmse"]
        run = json.loads((out / row["run_dir"] / "run.json").read_text())
        assert run["config"]["particles"] == particles and run["config"]["seed"] == seed
    summary = sweep_table.summarize(df, ["particles"])
    assert list(summary["particles"]) == [20, 40] and list(summary["ok"]) == [2, 2]
    assert (summary["ate_aligned_min"] <= summary["ate_aligned_median"]).all()
    assert "4 runs in the table (4 ok, 0 failed)" in res.output


@pytest.mark.slow
def test_a_rerun_runs_only_what_is_missing_and_rebuilds_the_whole_table(grid, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(grid[0], out)
    spec = grid[0].parent / "spec.yaml"
    gone = out / "runs/sim/particles=40/seed0"
    (gone / "result.json").unlink()
    (out / "results.csv").unlink()
    before = {p: p.stat().st_mtime_ns for p in out.glob("runs/sim/*/seed*/run.json")}
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(out), "--workers", "2"])
    assert res.exit_code == 0, res.output
    assert "3 done already, 1 to run" in res.output
    changed = [p for p, t in before.items() if p.stat().st_mtime_ns != t]
    assert changed == [gone / "run.json"]
    df = pd.read_csv(out / "results.csv")
    assert len(df) == 4 and (df["status"] == "ok").all()
    assert (gone / "result.json").is_file()


@pytest.mark.slow
def test_failed_runs_are_recorded_and_the_others_go_on(sim, tmp_path):
    corrupt = tmp_path / "corrupt.log"
    corrupt.write_bytes(b"\x00\x01 this is no log\n")
    spec = _write_spec(
        tmp_path,
        {
            "logs": [_sim_log(sim, "good"), {"name": "bad", "path": "corrupt.log"}],
            "seeds": [0, 1],
            "settings": {"particles": [20]},
        },
    )
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(tmp_path / "out"), "--workers", "2"])
    assert res.exit_code == 1, res.output
    df = pd.read_parquet(tmp_path / "out" / "results.parquet")
    status = {(r.log, r.seed): (r.status, r.exit_code, r.message) for r in df.itertuples()}
    assert status[("good", 0)] == status[("good", 1)] == ("ok", 0, "")
    for seed in (0, 1):
        st, code, message = status[("bad", seed)]
        assert st == "error" and code == 2 and "corrupt.log" in message and "unknown log format" in message
    assert "2 ok, 2 failed" in res.output


def test_a_run_killed_by_a_signal_is_recorded_as_killed(sim, tmp_path, monkeypatch):
    (tmp_path / "spec.yaml").write_text("")
    spec = sweep_spec.parse_spec({"logs": [_sim_log(sim)], "seeds": [0]}, tmp_path / "spec.yaml")
    job = sweep_jobs.make_jobs(spec, tmp_path / "out")[0]
    # (the out-of-memory killer's way: SIGKILL, no word from the run itself)
    kill = "import os, signal; os.kill(os.getpid(), signal.SIGKILL)"
    monkeypatch.setattr(sweep_jobs.Job, "command", lambda self: [sys.executable, "-c", kill])
    row = sweep_runner.run_job(job)
    assert (row["status"], row["exit_code"], row["message"]) == ("killed", -signal.SIGKILL, "killed by SIGKILL")


def test_a_run_past_its_time_limit_is_killed_and_marked_timeout(sim, tmp_path, monkeypatch):
    (tmp_path / "spec.yaml").write_text("")
    spec = sweep_spec.parse_spec({"logs": [_sim_log(sim)], "seeds": [0]}, tmp_path / "spec.yaml")
    job = sweep_jobs.make_jobs(spec, tmp_path / "out", timeout=0.5)[0]
    # A run that never ends by itself, however fast or busy the machine: only the limit stops it.
    monkeypatch.setattr(sweep_jobs.Job, "command", lambda self: [sys.executable, "-c", "import time; time.sleep(3600)"])
    row = sweep_runner.run_job(job)
    assert row["status"] == "timeout" and row["exit_code"] == -signal.SIGKILL and row["ate_aligned"] is None
    assert json.loads((job.folder / "result.json").read_text())["status"] == "timeout"


@pytest.mark.slow
def test_an_existing_cluster_is_used_through_scheduler(sim, tmp_path):
    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "distributed.cli.dask_scheduler",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    "0",
                    "--no-dashboard",
                    "--scheduler-file",
                    str(sched_file),
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
        for _ in range(2):
            procs.append(
                subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "distributed.cli.dask_worker",
                        "--scheduler-file",
                        str(sched_file),
                        "--nworkers",
                        "1",
                        "--nthreads",
                        "1",
                        "--host",
                        "127.0.0.1",
                        "--no-dashboard",
                        # one process each: a worker under a nanny takes some 8 s to shut down
                        "--no-nanny",
                    ],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
        deadline = time.monotonic() + 300  # a guard against hanging, not a speed check
        while not sched_file.is_file() or not sched_file.read_text().strip():
            assert time.monotonic() < deadline, "the scheduler did not start"
            assert procs[0].poll() is None, "the scheduler exited"
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        spec = _write_spec(tmp_path, {"logs": [_sim_log(sim)], "seeds": [0, 1]})
        res = runner.invoke(app, ["sweep", str(spec), "-o", str(tmp_path / "out"), "--scheduler", address])
        assert res.exit_code == 0, res.output
        assert f"on the Dask cluster at {address}" in res.output
        df = pd.read_csv(tmp_path / "out" / "results.csv")
        assert len(df) == 2 and (df["status"] == "ok").all() and df["ate_aligned"].notna().all()
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.mark.slow
def test_a_sweep_runs_a_ros2_bag_folder(sim, tmp_path):
    bag = tmp_path / "sim_bag"
    res = runner.invoke(app, ["convert", str(sim.lidar_path), str(bag), "-j", str(sim.joint_path), "--to", "ros2"])
    assert res.exit_code == 0, res.output
    spec = _write_spec(
        tmp_path,
        {
            "logs": [
                {"name": "bag", "path": str(bag), "ground_truth": str(sim.groundtruth_path), "args": ["--every", "4"]}
            ],
            "seeds": [0],
            "settings": {"particles": [20]},
        },
    )
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(tmp_path / "out"), "--workers", "1"])
    assert res.exit_code == 0, res.output
    df = pd.read_csv(tmp_path / "out" / "results.csv")
    assert len(df) == 1 and df["status"].iloc[0] == "ok", df.to_dict("records")
    assert df["scans"].iloc[0] == 100 and df["ate_aligned"].iloc[0] < 0.3


# -- localize sweeps -------------------------------------------------------------------------


def _localize_files(folder: Path) -> None:
    """A log and a map.yaml for specs that are only parsed (their contents are not read)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("a.log", "map.yaml"):
        (folder / name).write_text("x")


@pytest.mark.parametrize(
    "change, key, words",
    [
        ({"run": "localize", "map": None}, "logs[0] (a)", "needs 'map' with 'run: localize'"),
        ({"run": "localise"}, "run", "did you mean 'localize'?"),
        (
            {"logs": [{"name": "a", "path": "a.log", "map": "map.yaml"}]},
            "logs[0] (a).map",
            "only means something with 'run: localize'",
        ),
        (
            {"run": "localize", "settings": {"beam_temprature": [5, 10]}},
            "settings.beam_temprature",
            "unknown config key 'beam_temprature' (did you mean 'beam_temperature'?)",
        ),
        (
            {"run": "localize", "settings": {"local_search.enabled": [True]}},
            "settings.local_search.enabled",
            "a slam setting",
        ),
        ({"settings": {"sigma_hit_adapt": [True]}}, "settings.sigma_hit_adapt", "add 'run: localize'"),
        ({"run": "localize", "settings": {"beams": [0]}}, "settings.beams", "at least 1"),
        (  # each value valid, the combination not
            {"run": "localize", "settings": {"min_particles": [600], "max_particles": [550]}},
            "settings",
            "min_particles=600,max_particles=550: need 1 <= min_particles <= max_particles",
        ),
        ({"run": "localize", "args": ["--map", "map.yaml"]}, "logs[0] (a).args", "--map is set by the sweep"),
        ({"run": "localize", "args": ["-m", "map.yaml"]}, "logs[0] (a).args", "-m is set by the sweep"),
        ({"run": "localize", "args": ["-mmap.yaml"]}, "logs[0] (a).args", "-m is set by the sweep"),
        ({"run": "localize", "args": ["--map=map.yaml"]}, "logs[0] (a).args", "--map is set by the sweep"),
        ({"run": "localize", "args": ["-oout"]}, "logs[0] (a).args", "-o is set by the sweep"),
        ({"run": "localize", "map": "nomap"}, "logs[0] (a).map", "a folder without map.yaml"),
        ({"run": "localize", "map": "missing.yaml"}, "logs[0] (a).map", "map file not found"),
    ],
)
def test_a_bad_localize_spec_is_one_line_naming_the_spec_and_the_key(tmp_path, change, key, words):
    _localize_files(tmp_path)
    (tmp_path / "nomap").mkdir()
    # "map" and "args" go to the log (map.yaml by default in a localize spec, none if None).
    change = dict(change)  # (the parameters are not this test's to change)
    log = {"name": "a", "path": "a.log", **{k: change.pop(k) for k in ("map", "args") if k in change}}
    if change.get("run") == "localize":
        log.setdefault("map", "map.yaml")
    if log.get("map", "") is None:
        del log["map"]
    _one_line_spec_error(tmp_path, {"logs": [log], "seeds": [0], **change}, key, words)


def test_a_localize_spec_runs_pfslam_localize_on_each_logs_map(tmp_path):
    for seed in (3, 4):
        _localize_files(tmp_path / f"walk{seed}")
    slam_out = tmp_path / "slam_out"  # a pfslam slam output folder is a map too
    _localize_files(slam_out)
    spec = sweep_spec.parse_spec(
        {
            "run": "localize",
            "logs": [
                {
                    "name": "walk",
                    "path": "walk{seed}/a.log",
                    "map": "walk{seed}/map.yaml",
                    "odometry": "synthetic:{seed}",
                    "args": ["--global", "--initial-std", "0.2,0.2,10"],
                },
                {"name": "other", "path": "slam_out/a.log", "map": "slam_out"},
            ],
            "seeds": [3, 4],
            "settings": {"beam_temperature": [5, 10], "sigma_hit_adapt": [False, True]},
        },
        tmp_path / "spec.yaml",
    )
    assert spec.run == "localize" and spec.logs[1].map == slam_out
    assert spec.settings == {"beam_temperature": (5.0, 10.0), "sigma_hit_adapt": (False, True)}
    jobs = sweep_jobs.make_jobs(spec, tmp_path / "out")
    assert len(jobs) == spec.runs == 2 * 2 * 2 * 2
    assert len({j.fingerprint for j in jobs}) == len(jobs)
    job = jobs[3]
    assert (job.seed, job.settings) == (4, {"beam_temperature": 5.0, "sigma_hit_adapt": True})
    cmd = job.command()
    assert cmd[3:5] == ["localize", str(tmp_path / "walk4" / "a.log")]
    assert cmd[cmd.index("--map") + 1] == str(tmp_path / "walk4" / "map.yaml")
    assert cmd[cmd.index("--seed") + 1] == "4" and cmd[cmd.index("--odometry") + 1] == "synthetic:4"
    assert cmd[-3:] == ["--global", "--initial-std", "0.2,0.2,10"]
    assert job.run_dir == "runs/walk/beam_temperature=5.0,sigma_hit_adapt=true/seed4"
    assert jobs[-1].command()[cmd.index("--map") + 1] == str(slam_out)
    # The same inputs as a slam job are another job: a slam run's row is not a localize run's.
    as_slam = sweep_jobs.Job(**{**job.__dict__, "run": "slam", "map": None})
    assert as_slam.fingerprint != job.fingerprint


def test_a_slam_job_keeps_the_fingerprint_and_columns_it_had_before_localize_sweeps():
    """Runs of sweeps made before ``run:`` existed stay done (their result.json's fingerprint
    still matches), and a slam sweep's table has the same columns as then."""
    job = sweep_jobs.Job(
        log="a",
        path="/data/a.log",
        joint=None,
        odometry="synthetic:3",
        ground_truth=None,
        relations=None,
        time_offset=0.0,
        args=("--every", "2"),
        settings={"particles": 20},
        seed=3,
        out_dir="/o",
        run_dir="runs/a/particles=20/seed3",
    )
    assert job.fingerprint == "c683d14bd3c923a9b9d927b39b2834e2bfca709d"  # computed before `run:` was added
    assert job.command()[3] == "slam" and "--map" not in job.command()
    assert sweep_columns.metric_columns("slam") == sweep_columns.METRICS
    assert not set(sweep_columns.LOCALIZE_METRICS) & set(sweep_table.build_table([], ["particles"]).columns)
    assert "settle_s" not in sweep_table.summarize(sweep_table.build_table([], []), []).columns


def test_a_localize_run_that_never_settled_has_no_settle_time_and_is_counted(tmp_path, monkeypatch):
    """The localize figures come from run.json's metrics.estimate and filter sections (not
    metrics.SLAM); a run that never settled leaves settle_s empty, and the summary (table,
    printed, picture) counts it apart. The runs are stand-ins writing a run.json, run in
    this process (no cluster)."""
    _localize_files(tmp_path)
    spec = _write_spec(
        tmp_path, {"run": "localize", "logs": [{"name": "a", "path": "a.log", "map": "map.yaml"}], "seeds": [0, 1]}
    )

    def command(job):
        settle = None if job.seed == 0 else 2.5
        estimate = {"ate_rmse": 0.05, "ate_rmse_aligned": 0.04, "heading_rmse_deg": 1.0, "rpe_trans_rmse": 0.01}
        estimate["within_after_s"] = None if job.seed == 0 else 4.0  # seed 0 ended off the robot
        info = {
            "run": "localization",
            "scans_processed": 10,
            "metrics": {"estimate": estimate, "SLAM": {"ate_rmse_aligned": 9.0}},  # SLAM: not a localize run's
            "filter": {"recoveries": 3 + job.seed, "settle": {"seconds": settle, "at_s": settle}},
        }
        info["metrics"]["health"] = {
            "seconds_in_state": {"tracking": 9.0, "degraded": 0.5, "lost": 1.5 * job.seed, "ambiguous": 0.0},
            "lowest_quality": 0.4 - 0.1 * job.seed,
        }
        write = f"import pathlib; pathlib.Path({str(job.folder / 'run.json')!r}).write_text({json.dumps(info)!r})"
        return [sys.executable, "-c", write]

    def run_here(jobs, client, on_result=None):
        rows = [sweep_runner.run_job(job) for job in jobs]
        for row in rows:
            on_result(row)
        return rows

    monkeypatch.setattr(sweep_jobs.Job, "command", command)
    monkeypatch.setattr(sweep_runner, "dask_client", lambda workers=None, scheduler=None: contextlib.nullcontext())
    monkeypatch.setattr(sweep_runner, "run_jobs", run_here)
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert (df["status"] == "ok").all() and (df["ate_aligned"] == 0.04).all() and df["sigma_hit"].isna().all()
    assert df["settle_s"].isna().tolist() == [True, False] and df["recoveries"].tolist() == [3, 4]
    assert str(df["recoveries"].dtype) == "Int64"
    cfg = yaml.safe_load((tmp_path / "out" / df["run_dir"].iloc[0] / sweep_jobs.CONFIG_FILE).read_text())
    assert list(cfg) == ["localize"] and cfg["localize"]["beam_temperature"] == 10.0
    rec = sweep_table.summarize(df, []).iloc[0]
    assert rec["unsettled"] == 1 and rec["settle_s_median"] == 2.5 and rec["ate_aligned_median"] == 0.04
    assert df["within_after_s"].isna().tolist() == [True, False] and rec["off_at_end"] == 1
    assert rec["within_after_s_median"] == 4.0
    assert df["lost_s"].tolist() == [0.0, 1.5] and df["degraded_s"].tolist() == [0.5, 0.5]
    assert df["quality_min"].tolist() == pytest.approx([0.4, 0.3]) and rec["lost_s_median"] == 0.75
    assert "never settled" in res.output and "settle (s)" in res.output
    assert "off at the end" in res.output and "within 0.3 m after (s)" in res.output
    assert (tmp_path / "out" / "summary.png").is_file()


@pytest.fixture(scope="module")
def localize_grid(sim, tmp_path_factory):
    """A 2-setting localize sweep of the simulated log on its true map, seed 1 (not the
    default 0), one worker."""
    folder = tmp_path_factory.mktemp("localize_grid")
    log = {**_sim_log(sim, "walk"), "map": str(sim.lidar_path.parent / "map.yaml")}
    spec = _write_spec(
        folder,
        {"run": "localize", "logs": [log], "seeds": [1], "settings": {"sigma_hit_adapt": [False, True]}},
    )
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(folder / "out"), "--workers", "1"])
    return folder / "out", res


@pytest.mark.slow
def test_a_localize_sweep_gives_the_localization_figures_of_each_run(localize_grid):
    out, res = localize_grid
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out / "results.parquet")
    assert len(df) == 2 and (df["status"] == "ok").all(), df[["status", "message"]].to_dict("records")
    assert sorted(zip(df["sigma_hit_adapt"], df["seed"])) == [(False, 1), (True, 1)]
    assert (df["ate_aligned"] < 0.2).all() and (df["ate_raw"] < 0.2).all() and (df["scans"] == 400).all()
    assert (df["settle_s"] >= 0).all() and (df["recoveries"] >= 0).all()
    assert df["map_agreement"].isna().all() and df["relations_trans"].isna().all()
    # The field's width is fitted (and reported) only with sigma_hit_adapt.
    assert df.loc[df["sigma_hit_adapt"], "sigma_hit"].between(0.05, 0.3).all()
    assert df.loc[~df["sigma_hit_adapt"], "sigma_hit"].isna().all()
    for row in df.itertuples():
        folder = out / row.run_dir
        cfg = yaml.safe_load((folder / sweep_jobs.CONFIG_FILE).read_text())
        assert cfg["localize"]["sigma_hit_adapt"] == row.sigma_hit_adapt
        info = json.loads((folder / "run.json").read_text())
        assert info["run"] == "localization" and info["input"]["map"].endswith("map.yaml")
        assert info["config"]["sigma_hit_adapt"] == row.sigma_hit_adapt and info["config"]["seed"] == row.seed
        assert row.ate_aligned == info["metrics"]["estimate"]["ate_rmse_aligned"]
        assert row.settle_s == info["filter"]["settle"]["seconds"]
        assert row.within_after_s == info["metrics"]["estimate"]["within_after_s"] and row.within_after_s >= 0
        health = info["metrics"]["health"]
        assert row.lost_s == health["seconds_in_state"]["lost"] == 0 and row.quality_min == health["lowest_quality"]
        assert health["final_state"] == "tracking" and row.quality_min > 0.5
    summary = sweep_table.summarize(df, ["sigma_hit_adapt"])
    assert list(summary["ok"]) == [1, 1] and summary["settle_s_median"].notna().all()
    assert (out / "summary.png").stat().st_size > 10_000
    assert "settle (s)" in res.output and "2 runs in the table (2 ok, 0 failed)" in res.output
