"""The other commands: ``simulate``, ``demo``, ``evaluate``, ``sweep``, ``dump-config``, ``version``."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, Any, Optional

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from pfslam import __version__
from pfslam.cli.app import (
    EXIT_INTERRUPTED,
    INPUT,
    OUTPUT,
    Stdout,
    command,
    err_console,
    error,
    guarded,
    out_console,
    received_signals,
    warn,
)
from pfslam.cli.options import (
    SEED_HELP,
    Backend,
    Every,
    FilterName,
    Rerun,
    RerunSave,
    Search,
    Video,
    VideoFps,
    arg,
    cleaned_up,
    opt,
    scan_limit,
    settings_from,
    views_from,
)
from pfslam.cli.render import Printer, errors_table, report
from pfslam.errors import InputError
from pfslam.eval.table import METRICS

WORLD = "World"


SimOut = Annotated[
    Path,
    opt("--out", "-o", metavar="DIR", panel=OUTPUT, help="Output folder for the THOR-format log and the ground truth."),
]
World = Annotated[
    str,
    opt(
        "--world",
        "-w",
        metavar="NAME",
        panel=WORLD,
        help="office (default), corridor, or a world that repeats itself to fool loop closing: pillars "
        "(a corridor ring with a pillar and a door every 3 m), rooms (six identical rooms in a row), "
        "twins (two identical corridors walked the same way) or block (a 3 m corridor all round a "
        "central block, runs of 32 and 16 m of mostly bare walls), colonnade (a corridor loop lined with 0.5 m "
        "pillars at uneven spacing); or one whose walls say little: bare "
        "(100 m of bare corridor, out and back) or hall (an open 30 x 20 m hall, for a short-range laser: "
        "--robot wheeled --max-range 5.6); or random: a random building, one per --seed (a corridor loop "
        "round one block or a figure of eight round two, 2-4 m wide, with pillars, notches, doors and side rooms); "
        "or campus: an outdoor campus, one per --seed (about 250 x 250 m of buildings, trees, lamp poles and parked "
        "cars, an open lawn wider than the laser's reach, a 1.2-2 km route round blocks and across the lawn; the "
        "wheeled robot drives it once round at 1 m/s with a SICK LMS: 361 beams over 180 deg, 80 m).",
    ),
]
SimDuration = Annotated[
    Optional[float],
    opt(
        "--duration",
        metavar="S",
        panel=WORLD,
        help="Seconds of log (default 180; the wheeled robot in the campus: one lap of its route).",
    ),
]
WorldSeed = Annotated[int, opt("--seed", metavar="N", panel=WORLD, help=SEED_HELP)]
Gait = Annotated[
    str,
    opt(
        "--gait",
        metavar="NAME",
        panel=WORLD,
        help="calm (default: the demo's walk) or rough: 6 cm sway, corners turned in place with "
        "the head pitched to the floor, the head nodding 10-45 deg down, odometry drifting 0.8 deg/m.",
    ),
]
HeadPitch = Annotated[
    Optional[float],
    opt(
        "--head-pitch-deg",
        metavar="DEG",
        panel=WORLD,
        help="Hold the head at this pitch (positive = down) instead of moving it.",
    ),
]
Route = Annotated[
    str,
    opt(
        "--route",
        metavar="NAME",
        panel=WORLD,
        help="loop (default) or reverse: the same corridors the other way round, from half way along.",
    ),
]
NoDrift = Annotated[bool, opt("--no-drift", panel=WORLD, help="Odometry without scale error and heading bias.")]
OdometryScale = Annotated[
    Optional[float],
    opt(
        "--odometry-scale",
        metavar="X",
        panel=WORLD,
        help="The odometry reads X times the true travel (1.04: 4 % long; default a seeded random scale).",
    ),
]
Layout = Annotated[
    str,
    opt("--layout", metavar="NAME", panel=OUTPUT, help="Odometry field: penn (default: pose) or ucsd (delta_pose)."),
]
Robot = Annotated[
    str,
    opt(
        "--robot",
        metavar="NAME",
        panel=WORLD,
        help="humanoid (default: a THOR log) or wheeled: a robot with a planar lidar (720 beams over "
        "270 deg, 20 m; in the campus 361 over 180 deg, 80 m) driving the route at 0.6 m/s (the campus: 1 m/s), "
        "written as a ROS bag with its odometry in /tf.",
    ),
]
MaxRange = Annotated[
    Optional[float],
    opt(
        "--max-range",
        metavar="M",
        panel=WORLD,
        help="The wheeled robot's laser reach (m, default 20, the campus 80; 5.6 for a Hokuyo URG in the hall).",
    ),
]
Beams = Annotated[
    Optional[int],
    opt(
        "--beams",
        metavar="N",
        panel=WORLD,
        help="The wheeled robot's laser beams, spread evenly over --fov (default 720, the campus 361).",
    ),
]
Fov = Annotated[
    Optional[float],
    opt(
        "--fov",
        metavar="DEG",
        panel=WORLD,
        help="The wheeled robot's laser field of view (deg, at most 360; default 270, the campus 180; "
        "360: all round, the last beam one step short of the first).",
    ),
]
Speed = Annotated[
    Optional[float],
    opt(
        "--speed",
        metavar="M/S",
        panel=WORLD,
        help="The wheeled robot's speed (m/s, up to 5; default 0.6, the campus 1).",
    ),
]
BagKind = Annotated[
    str,
    opt(
        "--bag",
        metavar="KIND",
        panel=OUTPUT,
        help="The wheeled robot's bag: ros1 (default: OUT/log.bag), ros2 (the folder OUT/log) or mcap (OUT/log.mcap).",
    ),
]


@command()
@guarded
def simulate(
    out: SimOut,
    world: World = "office",
    duration: SimDuration = None,
    seed: WorldSeed = 0,
    gait: Gait = "calm",
    head_pitch_deg: HeadPitch = None,
    no_drift: NoDrift = False,
    odometry_scale: OdometryScale = None,
    route: Route = "loop",
    layout: Layout = "penn",
    robot: Robot = "humanoid",
    bag: BagKind = "ros1",
    max_range: MaxRange = None,
    beams: Beams = None,
    fov: Fov = None,
    speed: Speed = None,
) -> None:
    """Simulate a THOR humanoid log (or a wheeled robot's ROS bag) in a built-in world.

    Writes the lidar and joint .mat files (or the bag), groundtruth.tum and the true map.yaml into OUT."""
    from pfslam.errors import ConfigError
    from pfslam.tools.simulate import simulate as sim

    if robot not in ("humanoid", "wheeled"):
        raise ConfigError(f"--robot must be humanoid or wheeled, not {robot!r}")
    if robot == "wheeled":
        laser = (max_range, beams, fov, speed)
        _simulate_wheeled(
            out, world, duration, seed, route, bag, odometry_scale, no_drift, gait, head_pitch_deg, layout, laser
        )
        return
    wheeled = [
        n
        for n, v in (("--max-range", max_range), ("--beams", beams), ("--fov", fov), ("--speed", speed))
        if v is not None
    ]
    if wheeled:
        raise ConfigError(f"{', '.join(wheeled)}: the wheeled robot's (--robot wheeled), not the humanoid's")
    if duration is None:
        duration = 180.0
    if head_pitch_deg is not None and not abs(head_pitch_deg) <= 90.0:
        raise ConfigError(f"--head-pitch-deg must be a number of degrees within +-90, not {head_pitch_deg}")
    pitch = None if head_pitch_deg is None else float(np.deg2rad(head_pitch_deg))
    if odometry_scale is not None and no_drift:
        raise ConfigError("--odometry-scale is a drift: it cannot go with --no-drift")
    from pfslam.io.folders import prepare_output_dir
    from pfslam.pipeline.commands import DEMO_RATE_HZ

    limit = scan_limit()
    if limit is not None and duration > limit / DEMO_RATE_HZ:  # no run would read the rest
        duration = limit / DEMO_RATE_HZ
        warn(f"at most {limit} scans are read: simulating {duration:g} s")
    with cleaned_up(out):
        prepare_output_dir(out)
        res = sim(
            world=world,
            duration_s=duration,
            seed=seed,
            out_dir=out,
            layout=layout,
            head_pitch=pitch,
            drift=not no_drift,
            gait=gait,
            odometry_scale=odometry_scale,
            route=route,
        )
    out_console.print(
        escape(
            f"wrote {res.lidar_path}, {res.joint_path}, {res.groundtruth_path} and the true "
            f"map {Path(res.lidar_path).parent / 'map.yaml'}"
        ),
        soft_wrap=True,
    )


def _simulate_wheeled(
    out: Path,
    world: str,
    duration: float | None,
    seed: int,
    route: str,
    bag: str,
    odometry_scale: float | None,
    no_drift: bool,
    gait: str,
    head_pitch_deg: float | None,
    layout: str,
    laser: tuple[float | None, int | None, float | None, float | None],
) -> None:
    """``pfslam simulate --robot wheeled``: the bag, the ground truth and the true map (``laser``:
    --max-range, --beams, --fov and --speed, None where not given: the world's default)."""
    from pfslam.config import check_int, check_number
    from pfslam.errors import ConfigError
    from pfslam.io.folders import prepare_output_dir
    from pfslam.tools.simcommon import MAX_DURATION
    from pfslam.tools.wheeled import drive, simulate_wheeled_bag

    humanoid = [
        name
        for name, given in (
            ("--gait", gait != "calm"),
            ("--head-pitch-deg", head_pitch_deg is not None),
            ("--layout", layout != "penn"),
            ("--no-drift", no_drift),
        )
        if given
    ]
    if humanoid:
        raise ConfigError(f"{', '.join(humanoid)}: the humanoid's, not for --robot wheeled")
    given = drive(world)
    max_range, beams, fov, speed = laser
    max_range = given.max_range if max_range is None else max_range
    beams = given.beams if beams is None else beams
    fov = given.fov_deg if fov is None else fov
    speed = given.speed if speed is None else speed
    check_number("--max-range", max_range, gt=0.0, le=100.0, what="a finite distance in metres")
    check_int("--beams", beams, 2, 100_000)
    check_number("--fov", fov, gt=0.0, le=360.0, what="a finite angle in degrees")
    check_number("--speed", speed, gt=0.0, le=5.0, what="a finite speed in m/s")
    if duration is not None:
        check_number("--duration", duration, gt=0.0, le=MAX_DURATION, what="a finite number of seconds")
    if fov >= 360.0:  # all round: the last beam one step short of the first, not on it
        fov *= (beams - 1) / beams
    with cleaned_up(out):
        prepare_output_dir(out)
        res = simulate_wheeled_bag(
            world,
            given.duration_s if duration is None else duration,
            seed,
            out,
            storage=bag,
            odometry_scale=odometry_scale,
            route=route,
            max_range=max_range,
            beams=beams,
            fov_deg=fov,
            speed=speed,
            heading_bias_deg_per_m=given.heading_bias_deg_per_m,
        )
    out_console.print(
        escape(f"wrote {res.bag}, {res.groundtruth_path} and the true map {out / 'map.yaml'}"), soft_wrap=True
    )


DemoOut = Annotated[Path, opt("--out", "-o", metavar="DIR", panel=OUTPUT, help="Output folder (default demo_out).")]
DemoDuration = Annotated[
    float, opt("--duration", metavar="S", panel=WORLD, help="Seconds of simulated log (default 180).")
]
DemoSeed = Annotated[
    int, opt("--seed", metavar="N", panel=WORLD, help="Random seed of the log and the filter (default 0).")
]


@command()
@guarded
def demo(
    out: DemoOut = Path("demo_out"),
    duration: DemoDuration = 180.0,
    seed: DemoSeed = 0,
    filter_: FilterName = None,
    every: Every = None,
    backend: Backend = None,
    search: Search = None,
    video: Video = None,
    video_fps: VideoFps = None,
    rerun: Rerun = False,
    rerun_save: RerunSave = None,
) -> None:
    """Simulate a THOR office loop, run SLAM on it, and score SLAM and odometry against ground truth."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig

    cfg = settings_from(
        SlamConfig,
        None,
        {
            "seed": ("--seed", seed),
            "every": ("--every", every),
            "local_search.enabled": ("--search", search),
            "filter": ("--filter", filter_),
            "backend": ("--backend", backend),
        },
    )
    views = views_from(video, video_fps, rerun, rerun_save)
    with cleaned_up(out):
        outcome = pipeline.demo(
            out, duration=duration, seed=seed, config=cfg, views=views, reporter=Printer(), max_scans=scan_limit()
        )
    report(outcome)
    rows = outcome.scores.errors
    if rows:
        out_console.print(
            escape(
                f"ATE SLAM {rows['SLAM'].ate_rmse:.3f} m, odometry "
                f"{rows['odometry'].ate_rmse:.3f} m; map: {outcome.out / 'map.png'}"
            ),
            soft_wrap=True,
        )


MATCHING = "Matching"


Estimate = Annotated[Path, arg("EST", "Estimated trajectory (TUM).")]
Reference = Annotated[
    Optional[Path],
    opt(
        "--reference",
        "-r",
        metavar="REF",
        panel=INPUT,
        help="Reference trajectory (TUM): ATE (raw and SE(2)-aligned) and RPE against it.",
    ),
]
Relations = Annotated[
    Optional[Path],
    opt(
        "--relations",
        metavar="FILE",
        panel=INPUT,
        help="SLAM-benchmark relations file (t1 t2 x y z roll pitch yaw), with or without REF.",
    ),
]
TimeOffset = Annotated[
    float,
    opt(
        "--time-offset",
        metavar="S",
        panel=INPUT,
        help="Subtracted from the relations' time stamps to reach the estimate's clock (default 0).",
    ),
]
MaxDt = Annotated[
    float,
    opt("--max-dt", metavar="S", panel=MATCHING, help="Largest time difference of two poses paired (default 0.02)."),
]
RpeDelta = Annotated[int, opt("--rpe-delta", metavar="N", panel=MATCHING, help="RPE over N poses (default 10).")]
Plot = Annotated[
    Optional[Path],
    opt(
        "--plot",
        metavar="DIR",
        panel=OUTPUT,
        help="Folder for evo-style pictures against REF: trajectory_error.png (the aligned estimate "
        "coloured by its error) and error_over_time.png.",
    ),
]


@command(allow_extra_args=True)  # a second argument is refused with a hint, see below
@guarded
def evaluate(
    ctx: typer.Context,
    estimate: Estimate,
    reference: Reference = None,
    relations: Relations = None,
    time_offset: TimeOffset = 0.0,
    max_dt: MaxDt = 0.02,
    rpe_delta: RpeDelta = 10,
    plot: Plot = None,
) -> None:
    """ATE (raw and SE(2)-aligned) and RPE against a reference, and/or the relations metric."""
    from pfslam.pipeline.evaluation import evaluate as measure
    from pfslam.pipeline.evaluation import relations_why

    if ctx.args:  # pfslam evaluate EST REF
        raise InputError(ctx.args[0], "give the reference with --reference: pfslam evaluate EST --reference REF")
    with cleaned_up(plot if reference is not None else None):
        res = measure(
            estimate, reference, relations, time_offset=time_offset, max_dt=max_dt, rpe_delta=rpe_delta, plot=plot
        )
    for w in res.warnings:
        warn(w)
    if res.errors is not None:
        out_console.print(errors_table({estimate.name: res.errors}))
        out_console.print(f"matched poses: {res.errors.matched}")
        if res.pictures:
            out_console.print(f"pictures: {', '.join(str(f) for f in res.pictures)}", soft_wrap=True)
    if (r := res.relations) is not None:
        out_console.print(
            f"relations: {r.matched} matched, {r.skipped} skipped ({relations_why(r, max_dt)}); translation "
            f"{r.trans_mean:.4f} ± {r.trans_std:.4f} m, rotation {r.rot_mean_deg:.3f} ± {r.rot_std_deg:.3f} deg",
            soft_wrap=True,
        )


RUNS = "Runs"


Spec = Annotated[
    Path, arg("SPEC", "Sweep spec (YAML): logs, seeds, settings, and run: slam or localize (see docs/sweeps.md).")
]
SweepOut = Annotated[
    Path,
    opt("--out", "-o", metavar="DIR", panel=OUTPUT, help="Output folder: runs/, results.csv/.parquet, summary.png."),
]
Workers = Annotated[
    Optional[int],
    opt(
        "--workers",
        "-w",
        metavar="N",
        panel=RUNS,
        help="Worker processes of the local Dask cluster (default: one per CPU).",
    ),
]
Scheduler = Annotated[
    Optional[str],
    opt(
        "--scheduler",
        metavar="ADDRESS",
        panel=RUNS,
        help="Run on an existing Dask cluster: its scheduler's address (tcp://HOST:PORT) or "
        "scheduler file. Its workers must see the logs and OUT at the same paths.",
    ),
]
Timeout = Annotated[
    Optional[float], opt("--timeout", metavar="S", panel=RUNS, help="Kill a run after S seconds (status timeout).")
]
RetryFailed = Annotated[
    bool, opt("--retry-failed", panel=RUNS, help="Run again the runs of OUT that ended in error, killed or timeout.")
]


@command()
@guarded
def sweep(
    spec: Spec,
    out: SweepOut,
    workers: Workers = None,
    scheduler: Scheduler = None,
    timeout: Timeout = None,
    retry_failed: RetryFailed = False,
) -> None:
    """Run `pfslam slam` or `localize` over every log × setting combination × seed of a spec, on Dask.

    Each run is the real `pfslam slam` in its own subprocess (with `run: localize` in the spec,
    `pfslam localize` on each log's `map`, its settings keys of `pfslam dump-config localize`),
    writing into OUT/runs/LOG/SETTINGS/seedK/; runs already done in OUT are skipped. Writes
    OUT/results.csv and results.parquet (one row per run; a localize run's also settle_s,
    recoveries, sigma_hit), prints a summary (median and min-max over the seeds) and plots it
    (OUT/summary.png).
    Exit code 1 if some run failed (error, killed, timeout), 130 after Ctrl-C (the finished runs kept)."""
    from pfslam.config import check_int, check_number
    from pfslam.sweep import whole as sweep_run
    from pfslam.sweep.runner import cpu_count
    from pfslam.sweep.spec import settings_text

    if workers is not None:
        check_int("--workers", workers, 1)
    if timeout is not None:
        check_number("--timeout", timeout, gt=0.0, what="a finite number of seconds")
    if workers is not None and scheduler is not None:
        warn("--workers is ignored with --scheduler: the cluster has its own workers")
    with cleaned_up(out):
        plan = sweep_run.plan(spec, out, timeout, retry_failed)
    grid, jobs, keys = plan.spec, plan.jobs, plan.keys
    where = f"the Dask cluster at {scheduler}" if scheduler else f"{workers or cpu_count()} local workers"
    err_console.print(
        escape(
            f"{len(jobs)} runs ({len(grid.logs)} log(s) x {len(grid.combinations())} setting combination(s) x "
            f"{len(grid.seeds)} seed(s)): {len(plan.rows)} done already, {len(plan.todo)} to run"
            f"{' on ' + where if plan.todo else ''}"
        ),
        highlight=False,
        soft_wrap=True,
    )

    def describe(row: dict[str, Any]) -> str:
        text = f"{row['log']} {settings_text(row['settings'])} seed {row['seed']}: {row['status']}"
        if row["status"] != "ok":
            return f"{text} ({row['message']}); see {out / row['run_dir']}/stderr.txt"
        ate = f", ATE aligned {row['ate_aligned']:.3f} m" if row.get("ate_aligned") is not None else ""
        return f"{text}{ate} ({row['seconds']:.1f} s)"

    prog = Progress(
        TextColumn("[bold]sweep"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[failed]} failed"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=err_console,
        disable=not err_console.is_terminal and "PFSLAM_PROGRESS" not in os.environ or not plan.todo,
        speed_estimate_period=7 * 86400.0,  # the ETA from every run of this sweep, not the last 30 s
    )
    failed = sum(r["status"] != "ok" for r in plan.rows.values())
    with prog:
        task = prog.add_task("sweep", total=len(jobs), completed=len(plan.rows), failed=failed)

        def on_result(row: dict[str, Any]) -> None:
            nonlocal failed
            failed += row["status"] != "ok"
            prog.update(task, completed=len(plan.rows), failed=failed)
            line = f"[{len(plan.rows)}/{len(jobs)}] {describe(row)}"
            if row["status"] != "ok":
                prog.console.print(f"[yellow]warning:[/] {escape(line)}", highlight=False, soft_wrap=True)
            elif prog.disable:
                prog.console.print(escape(line), highlight=False, soft_wrap=True)

        res = sweep_run.run(plan, workers, scheduler, on_result)
    received_signals().extend(res.signals)
    table, summary, csv, parquet, png = res.table, res.summary, res.csv, res.parquet, res.png

    def span(rec: Any, m: str, digits: int) -> str:
        med, lo, hi = rec[f"{m}_median"], rec[f"{m}_min"], rec[f"{m}_max"]
        if not np.isfinite(med):
            return "–"
        return f"{med:.{digits}f}" if lo == hi else f"{med:.{digits}f}\n[dim]{lo:.{digits}f}–{hi:.{digits}f}[/]"

    if len(summary):
        tab = Table(
            show_header=True,
            header_style="bold",
            title="median (min–max) over the seeds' ok runs",
            title_justify="left",
        )
        shown = (
            "ate_aligned", "ate_raw", "within_after_s", "settle_s", "relations_trans", "relations_rot_deg",
            "map_agreement", "scans_per_s",
        )  # fmt: skip
        columns = [(METRICS[m].heading, m, METRICS[m].digits) for m in shown]
        columns = [c for c in columns if f"{c[1]}_median" in summary and summary[f"{c[1]}_median"].notna().any()]
        unsettled = "unsettled" in summary and bool(summary["unsettled"].any())  # localize runs that never settled
        off = "off_at_end" in summary and bool(summary["off_at_end"].any())  # ... that ended off the robot
        tab.add_column("log")
        if keys:
            tab.add_column("settings")
        tab.add_column("ok / runs", justify="right")
        for name, _, _ in columns:
            tab.add_column(name, justify="right")
        if unsettled:
            tab.add_column("never settled", justify="right")
        if off:
            tab.add_column("off at the end", justify="right")
        for _, rec in summary.iterrows():
            cells = [escape(str(rec["log"]))]
            if keys:  # one key=value a line
                cells.append(escape("\n".join(settings_text({k: rec[k]}) for k in keys)))
            cells.append(
                f"{rec['ok']} / {rec['runs']}" if not rec["failed"] else f"[red]{rec['ok']}[/] / {rec['runs']}"
            )
            more = [str(int(rec["unsettled"]))] if unsettled else []
            more += [str(int(rec["off_at_end"]))] if off else []
            tab.add_row(*cells, *[span(rec, m, d) for _, m, d in columns], *more)
        # Piped into a file or a CI log the table keeps its width rather than wrapping to 80 columns.
        wide = out_console if out_console.is_terminal else Console(width=max(out_console.width, 160))
        wide.print(tab)
    bad = res.failed
    earlier = bad[~bad["run_dir"].isin(res.reported)]  # the failures of this sweep were reported as they came
    for _, rec in earlier.head(10).iterrows():
        warn(f"{rec['run_dir']}: {rec['status']} (in an earlier sweep; --retry-failed runs it again): {rec['message']}")
    if len(earlier) > 10:
        warn(f"... and {len(earlier) - 10} more runs failed in an earlier sweep (column 'status' of {csv})")
    pictures = f", {png}" if png is not None else ""
    out_console.print(
        escape(
            f"{len(table)} runs in the table ({len(table) - len(bad)} ok, {len(bad)} failed): "
            f"{csv}, {parquet}{pictures}"
        ),
        soft_wrap=True,
    )
    if res.interrupted:
        err_console.print(
            f"[yellow]interrupted:[/] {len(table)} of {len(jobs)} runs done; the same command goes on from there",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(EXIT_INTERRUPTED)
    if res.broken:
        error(res.broken)
        raise typer.Exit(2)
    if len(bad):
        raise typer.Exit(1)


Section = Annotated[
    Optional[str],
    arg("SECTION", "Print only this section (slam, localize or calibrate), without its heading."),
]


@command("dump-config")
@guarded
def dump_config_cmd(
    section: Section = None,
) -> None:
    """Print the default configuration as YAML, every section (edit it and pass it with --config)."""
    from pfslam.config import SECTIONS, dump_config, dump_sections

    if section is None:
        text = dump_sections(*(cls() for cls in SECTIONS.values()))
    elif section in SECTIONS:
        text = dump_config(SECTIONS[section]())
    else:
        raise InputError("dump-config", f"unknown section {section!r} (one of {', '.join(SECTIONS)})")
    Stdout().write(text)
    Stdout().flush()


@command()
def version() -> None:
    """Print the pfslam version."""
    out_console.print(__version__)
