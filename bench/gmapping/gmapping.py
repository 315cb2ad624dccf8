"""pfslam against GMapping, the peer to beat: whole processes on the same logs and the same odometry.

    python bench/gmapping/gmapping.py --logs intel fr079 --seed 0 --repeat 3   # about 15 minutes, nothing else running
    python bench/gmapping/gmapping.py --quick --logs intel                     # smoke test: one run each, no warm-up

GMapping (``gfs_nogui``) is built once from ../shared/tools/gmapping (its build.sh, about two
minutes on 2 cores) into out/gmapping/ and reused; its code never enters this repository.

Each corrected log of ../shared/data/carmen (or PFSLAM_DATA) is written once as a plain CARMEN
log by ``pfslam convert LOG X.log --odometry synthetic:SEED``: its FLASER lines carry the
drifting synthetic odometry, so both programs read the very same file. GMapping runs with
``-particles 30`` and its other defaults, except ``-maxrange`` and ``-maxUrange`` set 0.01 m
below the log's no-return value (the ``PARAM robot_front_laser_max`` that convert writes, 80 m
on Intel), as the ROS wrapper does: at its default of 80 m the no-return readings of 80 m would
count as walls. convert puts the laser's mount into each FLASER's laser pose, which GMapping
ignores: the bench adds the ``PARAM robot_frontlaser_offset`` GMapping reads it from
(``--gmapping-mount pfslam``, the default: the mount pfslam reads from that log's two poses,
which is none on a corrected log, whose two poses are one; ``--gmapping-mount log``: the source
log's own PARAM, -0.04 m on FR079, which pfslam does not use on a FLASER). pfslam runs ``pfslam
slam X.log`` with its defaults.

Frames: every trajectory is scored in the laser's frame, the frame of a corrected log's poses.
- The reference: a FLASER record's first pose, the laser's (CARMEN's format; the loader's
  ``reference`` is the record's second pose, the robot's, taken to the laser by the mount the
  log gives, ``relative(robot, laser)``: none on a corrected log, whose two poses are equal).
- pfslam's ``trajectory.tum``: the robot's (the filter's pose is the base the sensor mount
  hangs from), composed here with the planar mount pfslam read from the log it ran on.
- GMapping's path (GFS_TRAJ): its particles' poses, the robot's; its scan matcher puts the laser
  at ``pose ⊕ (robot_frontlaser_offset, 0, 0)``, so the path is composed with that offset.
On a corrected log with the default mount all three offsets are zero and nothing moves.

Timing: the wall clock of each whole process from outside (time.perf_counter around it), the two
programs alternately, a warm-up run of each first (not counted), then the median of --repeat
runs. ``ratio`` is GMapping's median wall over pfslam's: how many times faster pfslam is.
``pfslam loop`` is pfslam's filter loop alone (run.json's ``seconds``), shown beside its wall
clock and not used in the ratio. GMapping's SLAM work runs on one thread (its main thread polls
and shows about 200 % CPU); pfslam's map update uses every core, so each round also runs pfslam
with ``NUMBA_NUM_THREADS=1``: ``ratio_wall_1thread`` is the ratio per core. The filter's cost per
particle and update (µs, run.json's ``seconds_by_part`` over updates x particles: prediction,
matching, weighing, health, map update, resampling) is reported for both, so a change shows
where its time went.

Accuracy: the SE(2)-aligned ATE RMSE (m) of each trajectory, in the laser's frame, against the log's
corrected poses, matched in time (pfslam.eval.metrics); GMapping's path as it wrote it (the
robot's) is scored too, as ``gmapping_ate_aligned_robot_frame_m``. GMapping writes its best particle's path at its update
scans only (GFS_TRAJ: after 1 m or 0.5 rad of motion), pfslam a pose at every scan; pfslam's ATE
at GMapping's update scans alone is given too. Writes bench/gmapping/gmapping.json (or --out), with the
commit, machine and date that made it (``provenance``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, ROOT, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
GMAPPING_SRC = ROOT.parent / "shared" / "tools" / "gmapping"
GMAPPING_BUILD = ROOT / "out" / "gmapping"
MAX_RANGE_PARAM = "robot_front_laser_max"
OFFSET_PARAM = "robot_frontlaser_offset"
MAX_RANGE_MARGIN = 0.01  # m below the no-return value, as GMapping's ROS wrapper sets range_max - 0.01


def build_gmapping(src: Path, out: Path) -> Path:
    """The gfs_nogui binary: built once by ``src``/build.sh into ``out`` (reused when there)."""
    binary = out / "gfs_nogui"
    if os.access(binary, os.X_OK):
        return binary
    print(f"building GMapping into {out} (about two minutes) ...", flush=True)
    proc = subprocess.run(["bash", str(src / "build.sh"), str(out)], capture_output=True, text=True)
    if proc.returncode != 0 or not os.access(binary, os.X_OK):
        raise SystemExit(f"building GMapping failed:\n{proc.stdout[-1000:]}{proc.stderr[-2000:]}")
    return binary


PFSLAM_SRC = ROOT / "src"  # the pfslam measured: --src sets it


def pfslam_env(threads: int | None = None) -> dict[str, str]:
    """The environment of the pfslam processes: the measured src/ (this tree's unless --src) first;
    ``threads``: Numba's threads (default: one per core)."""
    env = {**os.environ, "PYTHONPATH": str(PFSLAM_SRC)}
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    return env


def no_return_value(log: Path) -> float:
    """The ``PARAM robot_front_laser_max`` of a log ``pfslam convert`` wrote (its no-return reading)."""
    with log.open() as f:
        for _, line in zip(range(20), f):
            tok = line.split()
            if len(tok) > 2 and tok[0] == "PARAM" and tok[1] == MAX_RANGE_PARAM:
                return float(tok[2])
    raise SystemExit(f"{log}: no PARAM {MAX_RANGE_PARAM} in its first lines")


def laser_mount(frames: list[Any], name: str) -> np.ndarray:
    """The laser's planar pose in the robot frame (x, y, theta) as pfslam read it from a log's scans
    (``relative(robot, laser)`` of each FLASER; none where the two poses are equal): their median,
    with a warning when the scans' mounts differ by more than 0.1 mm or 0.1 mrad (a log written
    with 6 decimals leaves some scans 1e-6 rad off)."""
    m = np.array([[f.mount[0, 3], f.mount[1, 3], np.arctan2(f.mount[1, 0], f.mount[0, 0])] for f in frames])
    mount = np.median(m, axis=0)
    if np.abs(m - mount).max() > 1e-4:
        print(
            f"warning: {name}: the scans' laser mounts differ (from {m.min(0)} to {m.max(0)}): the bench uses {mount}"
        )
    return np.where(np.abs(mount) < 1e-6, 0.0, mount)


def log_param(path: Path, name: str) -> float | None:
    """A ``PARAM name value`` of a CARMEN log (plain or gzip), read up to its first laser record."""
    import gzip

    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", errors="replace") as f:
        for line in f:
            tok = line.split()
            if tok and tok[0] in ("FLASER", "ROBOTLASER1"):
                break
            if len(tok) > 2 and tok[0] == "PARAM" and tok[1] == name:
                return float(tok[2])
    return None


def in_laser_frame(poses: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """Robot poses (N, 3) taken to the laser's: each composed with the laser's mount (x, y, theta)."""
    from pfslam.geometry import compose

    return compose(np.asarray(poses, dtype=float), np.asarray(mount, dtype=float)) if np.any(mount) else poses


def convert(src: Path, plain: Path, odometry: str, offset: float) -> None:
    """``pfslam convert`` ``src`` into ``plain`` (a CARMEN log with ``odometry``), plus, when
    ``offset`` is not 0, the PARAM ``robot_frontlaser_offset`` GMapping reads its laser's mount from
    (convert puts the mount in each FLASER's laser pose, which GMapping ignores; pfslam reads it
    there and not the PARAM)."""
    tmp = plain.with_name(plain.stem + ".convert.log")
    cmd = [sys.executable, "-m", "pfslam.cli", "convert", str(src), str(tmp), "--odometry", odometry, "--force"]
    proc = subprocess.run(cmd, env=pfslam_env(), capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"pfslam convert {src} failed: {proc.stderr[-1000:]}")
    with tmp.open() as f, plain.open("w") as out:
        for line in f:
            out.write(line)
            tok = line.split()
            if offset and len(tok) == 6 and tok[:2] == ["PARAM", MAX_RANGE_PARAM]:
                out.write(" ".join(["PARAM", OFFSET_PARAM, f"{offset:g}", *tok[3:]]) + "\n")
    tmp.unlink()


def prepare(name: str, seed: int, work: Path, gmapping_mount: str) -> dict[str, Any]:
    """The plain CARMEN log with synthetic odometry ``seed`` both programs read, its no-return
    value, the mounts each program puts the laser at, and the reference poses in the laser's frame
    (times, (N, 3)) the scores use (also written as reference.tum)."""
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import write_tum
    from pfslam.pipeline.prepare import reference_truth

    src = DATA / "carmen" / f"{name}.gfs.log.gz"
    if not src.exists():
        raise SystemExit(f"{src}: no such log (the names are those of {DATA / 'carmen'}/*.gfs.log.gz)")
    stem = f"{name}_s{seed}" + ("_logmount" if gmapping_mount == "log" else "")
    folder = work / stem
    folder.mkdir(parents=True, exist_ok=True)
    plain = folder / f"{stem}.log"
    odometry = f"synthetic:{seed}"
    loaded = load_log(src, odometry=odometry)
    truth = reference_truth(loaded)
    if truth is None:
        raise SystemExit(f"{src}: no reference poses (not a corrected log?)")
    t_ref, robot_ref = truth
    source_mount = laser_mount(loaded.frames, name)
    ref = in_laser_frame(robot_ref, source_mount)  # each FLASER's first pose, the laser's
    write_tum(folder / "reference.tum", t_ref, ref)
    if gmapping_mount == "log":
        offset = log_param(src, OFFSET_PARAM) or 0.0
    else:
        offset = float(source_mount[0])
        if source_mount[1] or source_mount[2]:
            print(f"warning: {name}: the laser's mount {source_mount} is more than GMapping's PARAM can say")
    if not plain.exists():
        convert(src, plain, odometry, offset)
    pfslam_mount = laser_mount(load_log(plain).frames, f"{name} as converted")
    return {
        "log": plain,
        "folder": folder,
        "max_range": no_return_value(plain),
        "gmapping_offset": offset,
        "pfslam_mount": pfslam_mount,
        "t_ref": t_ref,
        "ref": ref,
    }


def run_gmapping(binary: Path, log: Path, max_range: float, particles: int, out: Path) -> dict[str, Any]:
    """One gfs_nogui process (in ``out``: it writes rawpath.dat and w-*.dat where it runs)."""
    out.mkdir(parents=True, exist_ok=True)
    traj = out / "gmapping.txt"
    limit = f"{max_range - MAX_RANGE_MARGIN:g}"
    cmd = [str(binary), "-filename", str(log), "-particles", str(particles), "-maxrange", limit, "-maxUrange", limit]
    env = {**os.environ, "GFS_TRAJ": str(traj)}
    with (out / "stdout.txt").open("wb") as so, (out / "stderr.txt").open("wb") as se:
        began = time.perf_counter()
        proc = subprocess.run(cmd, cwd=out, env=env, stdout=so, stderr=se)
        wall = time.perf_counter() - began
    if proc.returncode != 0 or not traj.exists():
        tail = (out / "stderr.txt").read_text(errors="replace")[-1000:]
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {tail}")
    rows = np.loadtxt(traj, ndmin=2)
    return {"wall_s": wall, "t": rows[:, 0], "poses": rows[:, 1:4], "command": cmd}


def run_pfslam(log: Path, out: Path, threads: int | None = None) -> dict[str, Any]:
    """One ``pfslam slam`` process with its defaults (``threads``: Numba's)."""
    from pfslam.io.trajectory import read_tum

    cmd = [sys.executable, "-m", "pfslam.cli", "slam", str(log), "-o", str(out)]
    began = time.perf_counter()
    proc = subprocess.run(cmd, env=pfslam_env(threads), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall = time.perf_counter() - began
    if proc.returncode != 0:
        raise SystemExit(f"pfslam slam {log} failed: {proc.stderr.decode(errors='replace')[-1000:]}")
    info = json.loads((out / "run.json").read_text())
    t, poses = read_tum(out / "trajectory.tum")
    return {
        "wall_s": wall,
        "loop_s": info.get("seconds"),
        "phases": info.get("seconds_by_phase"),
        "per_particle_update": per_particle_update(info.get("filter") or {}),
        "t": t,
        "poses": poses,
    }


def per_particle_update(diag: dict[str, Any]) -> dict[str, Any]:
    """The filter's cost per particle and map update (µs), by part (run.json's filter block:
    seconds_by_part over map_updates x particles), and how many it did."""
    n = (diag.get("map_updates") or 0) * (diag.get("particles") or 0)
    parts = diag.get("seconds_by_part") or {}
    return {
        "updates": diag.get("map_updates"),
        "particles": diag.get("particles"),
        "us": {k: round(1e6 * v / n, 1) for k, v in parts.items()} if n else {},
        "us_all": round(1e6 * sum(parts.values()) / n, 1) if n else None,
    }


def ate(t: np.ndarray, poses: np.ndarray, t_ref: np.ndarray, ref: np.ndarray) -> tuple[float, int]:
    """SE(2)-aligned ATE RMSE (m) and the number of poses matched in time."""
    from pfslam.eval.metrics import trajectory_errors

    e = trajectory_errors(t, poses, t_ref, ref)
    return e.ate_rmse_aligned, e.matched


def at_times(t: np.ndarray, poses: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The poses of (t, poses) at ``times`` (the same scans' stamps)."""
    from pfslam.eval.metrics import associate

    i, _ = associate(t, times, max_dt=1e-3)
    return t[i], poses[i]


def bench_log(name: str, a: argparse.Namespace, binary: Path, work: Path) -> dict[str, Any]:
    """Warm-up (unless --quick), then --repeat alternating runs of GMapping and pfslam on one log."""
    p = prepare(name, a.seed, work, a.gmapping_mount)
    print(
        f"{name}: {p['log']} (no-return {p['max_range']:g} m), {len(p['t_ref'])} scans; laser mount: "
        f"GMapping {p['gmapping_offset']:g} m ahead, pfslam {p['pfslam_mount'].tolist()}",
        flush=True,
    )
    gm: list[dict[str, Any]] = []
    pf: list[dict[str, Any]] = []
    one: list[dict[str, Any]] = []  # pfslam on one thread (GMapping's SLAM runs on one)
    rounds = ["warm-up"] * (0 if a.quick else 1) + [f"run {r + 1}" for r in range(a.repeat)]
    for k, label in enumerate(rounds):
        g = run_gmapping(binary, p["log"], p["max_range"], a.particles, p["folder"] / f"gmapping_{k}")
        s = run_pfslam(p["log"], p["folder"] / f"pfslam_{k}")
        s1 = run_pfslam(p["log"], p["folder"] / f"pfslam_1thread_{k}", threads=1)
        print(
            f"  {label}: GMapping {g['wall_s']:.1f} s, pfslam {s['wall_s']:.1f} s wall (loop {s['loop_s']:.1f} s), "
            f"one thread {s1['wall_s']:.1f} s (loop {s1['loop_s']:.1f} s)",
            flush=True,
        )
        if label != "warm-up":
            gm.append(g)
            pf.append(s)
            one.append(s1)
    t_ref, ref = p["t_ref"], p["ref"]  # the laser's poses
    gm_laser = np.array([p["gmapping_offset"], 0.0, 0.0])
    for g in gm:
        g["laser"] = in_laser_frame(g["poses"], gm_laser)
    for s in pf:
        s["laser"] = in_laser_frame(s["poses"], p["pfslam_mount"])
    gm_ate = [ate(g["t"], g["laser"], t_ref, ref) for g in gm]
    gm_ate_robot = [ate(g["t"], g["poses"], t_ref, ref) for g in gm]
    pf_ate = [ate(s["t"], s["laser"], t_ref, ref) for s in pf]
    pf_ate_gm = [ate(*at_times(s["t"], s["laser"], g["t"]), t_ref, ref) for g, s in zip(gm, pf)]
    gm_wall = statistics.median(g["wall_s"] for g in gm)
    pf_wall = statistics.median(s["wall_s"] for s in pf)
    one_wall = statistics.median(s["wall_s"] for s in one)
    return {
        "log": name,
        "odometry": f"synthetic:{a.seed}",
        "scans": len(t_ref),
        "no_return_m": p["max_range"],
        "gmapping_mount": a.gmapping_mount,
        "gmapping_laser_offset_m": p["gmapping_offset"],
        "pfslam_laser_mount_xyt": [round(float(v), 6) for v in p["pfslam_mount"]],
        "frames": {
            "reference": "laser: each FLASER's first pose (the source log's poses, taken by its mount)",
            "pfslam": "robot (trajectory.tum), composed with pfslam_laser_mount_xyt: laser",
            "gmapping": "robot (GFS_TRAJ), composed with (gmapping_laser_offset_m, 0, 0): laser",
        },
        "gmapping_command": " ".join(gm[-1]["command"][1:]),
        "gmapping_wall_s_median": round(gm_wall, 2),
        "pfslam_wall_s_median": round(pf_wall, 2),
        "ratio_wall": round(gm_wall / pf_wall, 2),
        "pfslam_loop_s_median": round(statistics.median(float(s["loop_s"]) for s in pf), 2),
        "pfslam_1thread_wall_s_median": round(one_wall, 2),
        "ratio_wall_1thread": round(gm_wall / one_wall, 2),
        "pfslam_1thread_loop_s_median": round(statistics.median(float(s["loop_s"]) for s in one), 2),
        "pfslam_1thread_ate_aligned_m": round(
            statistics.median(ate(s["t"], in_laser_frame(s["poses"], p["pfslam_mount"]), t_ref, ref)[0] for s in one), 4
        ),
        "pfslam_per_particle_update": pf[-1]["per_particle_update"],
        "pfslam_1thread_per_particle_update": one[-1]["per_particle_update"],
        "gmapping_ate_aligned_m": round(statistics.median(x for x, _ in gm_ate), 4),
        "gmapping_ate_aligned_robot_frame_m": round(statistics.median(x for x, _ in gm_ate_robot), 4),
        "pfslam_ate_aligned_m": round(statistics.median(x for x, _ in pf_ate), 4),
        "pfslam_ate_aligned_at_gmapping_scans_m": round(statistics.median(x for x, _ in pf_ate_gm), 4),
        "gmapping_poses_matched": gm_ate[-1][1],
        "pfslam_poses_matched": pf_ate[-1][1],
        "gmapping_wall_s": [round(g["wall_s"], 2) for g in gm],
        "pfslam_wall_s": [round(s["wall_s"], 2) for s in pf],
        "pfslam_loop_s": [round(float(s["loop_s"]), 2) for s in pf],
        "gmapping_ate_aligned_runs_m": [round(x, 4) for x, _ in gm_ate],
        "pfslam_ate_aligned_runs_m": [round(x, 4) for x, _ in pf_ate],
        "pfslam_phases_last": pf[-1]["phases"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", nargs="+", default=["intel", "fr079"], help="names of DATA/carmen/NAME.gfs.log.gz")
    ap.add_argument("--seed", type=int, default=0, help="synthetic odometry seed (default 0)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each program per log (default 3)")
    ap.add_argument("--quick", action="store_true", help="smoke test: one run each, no warm-up")
    ap.add_argument("--particles", type=int, default=30, help="GMapping's particles (default 30)")
    ap.add_argument("--gmapping-src", type=Path, default=GMAPPING_SRC, help="folder of GMapping's build.sh")
    ap.add_argument("--gmapping-build", type=Path, default=GMAPPING_BUILD, help="where gfs_nogui is built (cache)")
    ap.add_argument(
        "--gmapping-mount",
        choices=("pfslam", "log"),
        default="pfslam",
        help="the laser offset GMapping is given: the mount pfslam reads (default; none on a corrected log) "
        "or the source log's PARAM robot_frontlaser_offset",
    )
    ap.add_argument(
        "--src",
        type=Path,
        default=ROOT / "src",
        help="the pfslam src/ to measure (default this tree's; e.g. `git archive HEAD src | tar -x -C /tmp/head` "
        "to measure the commit while src/ is being edited)",
    )
    ap.add_argument("--work", type=Path, help="keep the logs and runs here (default: a temporary folder)")
    ap.add_argument("--out", type=Path, default=HERE / "gmapping.json")
    a = ap.parse_args()
    if a.quick:
        a.repeat = 1
    if a.repeat < 1:
        ap.error("--repeat must be at least 1")
    global PFSLAM_SRC
    PFSLAM_SRC = a.src.resolve()
    sys.path.insert(0, str(PFSLAM_SRC))  # this process's pfslam (loading, converting, scoring) too
    binary = build_gmapping(a.gmapping_src.resolve(), a.gmapping_build.resolve())
    prov = provenance(PFSLAM_SRC)
    print(f"GMapping: {binary}")
    print(f"machine: {prov['machine']}, load average {prov['load_average_at_start']}", flush=True)
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="pfslam-gmapping-") as tmp:
        work = a.work.resolve() if a.work else Path(tmp)
        for name in a.logs:
            rows.append(bench_log(name, a, binary, work))
            result = {
                "provenance": prov,
                "gmapping": str(binary),
                "repeat": a.repeat,
                "warm_up": not a.quick,
                "rows": rows,
            }
            a.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nmedians of {a.repeat} run(s){'' if a.quick else ' after a warm-up'}; {prov['machine']}")
    print("wall: whole process, timed from outside; loop: pfslam's filter loop alone (run.json `seconds`)")
    print("ATE: SE(2)-aligned, every trajectory in the laser's frame (the reference's)")
    print("one thread: NUMBA_NUM_THREADS=1 (GMapping's SLAM runs on one thread)")
    print(
        "| log | GMapping wall | pfslam wall | ratio | pfslam loop | one thread: wall, ratio, loop "
        "| ATE GMapping | ATE pfslam (at GMapping's scans) | one thread |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['log']} ({r['scans']} scans, {r['odometry']}) | {r['gmapping_wall_s_median']:.1f} s "
            f"| {r['pfslam_wall_s_median']:.1f} s | {r['ratio_wall']:.2f}x | {r['pfslam_loop_s_median']:.1f} s "
            f"| {r['pfslam_1thread_wall_s_median']:.1f} s, {r['ratio_wall_1thread']:.2f}x, "
            f"{r['pfslam_1thread_loop_s_median']:.1f} s "
            f"| {r['gmapping_ate_aligned_m']:.3f} m ({r['gmapping_poses_matched']}) "
            f"| {r['pfslam_ate_aligned_m']:.3f} m ({r['pfslam_ate_aligned_at_gmapping_scans_m']:.3f} m) "
            f"| {r['pfslam_1thread_ate_aligned_m']:.3f} m |"
        )
    print("\nthe filter's cost per particle and update (µs; two threads / one), by part:")
    for r in rows:
        two, one = r["pfslam_per_particle_update"], r["pfslam_1thread_per_particle_update"]
        parts = ", ".join(f"{k} {v} / {one['us'].get(k)}" for k, v in two["us"].items())
        print(
            f"  {r['log']}: {two['updates']} updates x {two['particles']} particles; all {two['us_all']} / {one['us_all']}: {parts}"
        )
    print(f"written {a.out}")


if __name__ == "__main__":
    main()
