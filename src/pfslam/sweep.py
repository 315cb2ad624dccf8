"""Sweeps: one command runs many logs × seeds × settings and collects one table.

A *spec* (YAML) names the logs, the seeds and the settings to vary::

    logs:
      - name: intel
        path: ../data/intel.gfs.log.gz       # relative to the spec's folder
        odometry: "synthetic:{seed}"          # {seed} becomes each run's seed
        relations: ../data/intel.relations
        time_offset: 976052857.338
    seeds: {from: 0, to: 4}                   # or a list
    settings:                                 # any config key, dotted; every combination runs
      local_search.enabled: [false, true]
      particles: {from: 50, to: 150, step: 50}

- :func:`load_spec` reads and validates a spec (every problem is an :class:`InputError`
  naming the spec file and the key); :func:`make_jobs` expands it into one :class:`Job`
  per log × setting combination × seed, each with its own run folder
  ``OUT/runs/<log>/<settings-slug>/seed<k>/``.
- :func:`run_job` executes one job: the real ``pfslam slam`` in a fresh subprocess (so a
  crash or a kill takes only that run down, and its peak memory is its own), then reads
  the run's ``run.json`` (and scores the relations, if the log has them) into a small row
  that it also writes to the run folder as ``result.json``: a run is done when that file
  is there. Only the job (paths, settings, seed) goes to a worker and only the row comes
  back: the logs are read where they are.
- :func:`run_jobs` runs jobs on Dask (a local cluster of processes, or an existing
  scheduler), reporting each row through a callback as it arrives.
- :func:`build_table`, :func:`summarize` and :func:`plot_summary` turn rows into the
  table (``results.csv``/``.parquet``), per-combination statistics and ``summary.png``.

Nothing here prints.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import logging
import math
import os
import re
import select
import signal
import subprocess
import sys
import time
import uuid
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator, Sequence

import yaml

from pfslam.errors import ConfigError, InputError

if TYPE_CHECKING:
    import pandas as pd

SPEC_KEYS = ("logs", "seeds", "settings")
LOG_KEYS = ("name", "path", "joint", "odometry", "ground_truth", "relations", "time_offset", "args")
RANGE_KEYS = ("from", "to", "step")
# Options of `pfslam slam` that the sweep sets itself: a log's `args` may not repeat them.
SWEEP_OPTIONS = ("-o", "--out", "-c", "--config", "--seed", "-j", "--joint", "-g", "--ground-truth", "--odometry")
MAX_VALUES = 10_000  # values of one range: more is a typo (a step of 0.0001)
MAX_RUNS = 100_000
STATUSES = ("ok", "error", "killed", "timeout")
RESULT_FILE = "result.json"
CONFIG_FILE = "sweep_config.yaml"
STDOUT_FILE = "stdout.txt"
STDERR_FILE = "stderr.txt"
# Files of an earlier attempt that must not be mistaken for this attempt's results.
_STALE = (RESULT_FILE, "run.json", "trajectory.tum")
# A run is one single-threaded process: libraries must not start a thread per core each.
THREAD_ENV = {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "MKL_NUM_THREADS": "1"}
# Test-only: kill the child of every run whose folder contains this text right after starting it.
TEST_KILL_ENV = "PFSLAM_SWEEP_TEST_KILL"

METRICS = ("ate_raw", "ate_aligned", "heading_rmse_deg", "rpe_trans", "relations_trans", "relations_rot_deg",
           "relations_count", "map_agreement", "odometry_map_agreement", "scans", "scans_per_s",
           "real_time_factor", "peak_rss_mb", "seconds")
COUNT_METRICS = ("scans", "relations_count")  # integers (empty where unknown)
HEAD_COLUMNS = ("log", "seed")
STATUS_COLUMNS = ("status", "exit_code", "message")
TAIL_COLUMNS = ("run_dir",)
# Summarised per log × setting combination (median and min-max over the ok runs), and plotted.
SUMMARY_METRICS = ("ate_aligned", "ate_raw", "relations_trans", "relations_rot_deg", "map_agreement",
                   "scans_per_s", "peak_rss_mb")
METRIC_LABELS = {
    "ate_aligned": "ATE aligned (m)", "ate_raw": "ATE raw (m)", "relations_trans": "relations trans (m)",
    "relations_rot_deg": "relations rot (deg)", "map_agreement": "map agreement", "scans_per_s": "scans/s",
    "peak_rss_mb": "peak RSS (MB)",
}


# -- the spec ------------------------------------------------------------------------------


@dataclass(frozen=True)
class LogSpec:
    """One log of a spec; paths are absolute."""

    name: str
    path: Path
    joint: Path | None = None
    odometry: str = "log"  # may hold {seed}
    ground_truth: Path | None = None
    relations: Path | None = None
    time_offset: float = 0.0
    args: tuple[str, ...] = ()


@dataclass(frozen=True)
class Spec:
    """A validated spec: logs, seeds, and the values of each setting (in the spec's order)."""

    path: Path
    logs: tuple[LogSpec, ...]
    seeds: tuple[int, ...]
    settings: dict[str, tuple[Any, ...]] = field(default_factory=dict)

    @property
    def setting_keys(self) -> list[str]:
        return list(self.settings)

    def combinations(self) -> list[dict[str, Any]]:
        """Every combination of the settings' values (one empty one without settings)."""
        keys = list(self.settings)
        return [dict(zip(keys, values)) for values in itertools.product(*self.settings.values())]

    @property
    def runs(self) -> int:
        return len(self.logs) * len(self.seeds) * math.prod(len(v) for v in self.settings.values())


def _fail(spec: Path, key: str, problem: str) -> InputError:
    return InputError(spec, f"{key}: {problem}")


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def expand_range(spec: Path, key: str, value: dict[str, Any], integer: bool = False) -> list[Any]:
    """The values ``from``, ``from + step``, ... up to ``to`` inclusive (``step`` 1 if not
    given). Integers stay integers; float steps are rounded to 12 significant digits so
    ``{from: 0.1, to: 0.3, step: 0.1}`` gives 0.1, 0.2, 0.3."""
    unknown = [k for k in value if k not in RANGE_KEYS]
    if unknown:
        raise _fail(spec, key, f"unknown range key {unknown[0]!r} (a range has from, to and optionally step)")
    for k in ("from", "to"):
        if k not in value:
            raise _fail(spec, key, f"a range needs '{k}' (a range is {{from: A, to: B, step: S}})")
    start, stop, step = value["from"], value["to"], value.get("step", 1)
    for k, v in (("from", start), ("to", stop), ("step", step)):
        if not _is_number(v) or not math.isfinite(v):
            raise _fail(spec, f"{key}.{k}", f"must be a finite number, not {_shown(v)}")
        if integer and not isinstance(v, int):
            raise _fail(spec, f"{key}.{k}", f"must be an integer, not {_shown(v)}")
    if step <= 0:
        raise _fail(spec, f"{key}.step", f"must be greater than 0, not {_shown(step)}")
    if stop < start:
        raise _fail(spec, key, f"'to' ({stop}) is below 'from' ({start})")
    count = int(math.floor((stop - start) / step + 1e-9)) + 1
    if count > MAX_VALUES:
        raise _fail(spec, key, f"the range has {count} values (at most {MAX_VALUES})")
    if all(isinstance(v, int) for v in (start, stop, step)):
        return [start + i * step for i in range(count)]
    return [float(f"{start + i * step:.12g}") for i in range(count)]


def _path(spec: Path, key: str, value: Any, what: str, bag_folder: bool = False) -> Path:
    """``value`` as an existing file's absolute path (relative to the spec's folder); with
    ``bag_folder`` a ROS 2 bag's folder is one too."""
    from pfslam.io.rosbag import is_ros2_folder

    if not isinstance(value, str) or not value.strip():
        raise _fail(spec, key, f"must be a path (a string), not {_shown(value)}")
    p = Path(value).expanduser()
    p = (spec.parent / p) if not p.is_absolute() else p
    p = Path(os.path.normpath(p.absolute()))
    if bag_folder and is_ros2_folder(p):
        return p
    if p.is_dir():
        extra = " or a ROS 2 bag (no metadata.yaml in it)" if bag_folder else ""
        raise _fail(spec, key, f"{p} is a folder, not a {what}{extra}")
    if not p.is_file():
        raise _fail(spec, key, f"{what} not found: {p}")
    return p


def _log_spec(spec: Path, i: int, entry: Any) -> LogSpec:
    from pfslam.odometry import parse_odometry_option

    where = f"logs[{i}]"
    if not isinstance(entry, dict):
        raise _fail(spec, where, f"must be a mapping with name, path, ... not {_shown(entry)}")
    unknown = [k for k in entry if k not in LOG_KEYS]
    if unknown:
        raise _fail(spec, f"{where}.{unknown[0]}", f"unknown key (a log has {', '.join(LOG_KEYS)})")
    for k in ("name", "path"):
        if k not in entry:
            raise _fail(spec, where, f"needs '{k}'")
    name = entry["name"]
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", name):
        raise _fail(spec, f"{where}.name", f"must be a plain name (letters, digits, . _ -), not {_shown(name)}")
    where = f"logs[{i}] ({name})"
    path = _path(spec, f"{where}.path", entry["path"], "log file", bag_folder=True)
    joint = _path(spec, f"{where}.joint", entry["joint"], "joint file") if entry.get("joint") is not None else None
    gt = (_path(spec, f"{where}.ground_truth", entry["ground_truth"], "ground truth file")
          if entry.get("ground_truth") is not None else None)
    odometry = entry.get("odometry", "log")
    if not isinstance(odometry, str):
        raise _fail(spec, f"{where}.odometry", f"must be 'log', 'synthetic' or 'synthetic:SEED', not {_shown(odometry)}")
    try:
        parse_odometry_option(odometry.replace("{seed}", "0"))
    except ValueError as e:
        raise _fail(spec, f"{where}.odometry", f"{e} ({{seed}} stands for the run's seed)") from None
    relations = None
    if entry.get("relations") is not None:
        from pfslam.evaluate import read_relations

        relations = _path(spec, f"{where}.relations", entry["relations"], "relations file")
        try:
            read_relations(relations)
        except InputError as e:
            raise _fail(spec, f"{where}.relations", str(e)) from None
    time_offset = entry.get("time_offset", 0.0)
    if not _is_number(time_offset) or not math.isfinite(time_offset):
        raise _fail(spec, f"{where}.time_offset", f"must be a finite number of seconds, not {_shown(time_offset)}")
    if "time_offset" in entry and relations is None:
        raise _fail(spec, f"{where}.time_offset", "only means something with 'relations'")
    args = entry.get("args") or []
    if not isinstance(args, list) or not all(isinstance(a, (str, int, float)) and not isinstance(a, bool)
                                             for a in args):
        raise _fail(spec, f"{where}.args", f"must be a list of command-line arguments, not {_shown(args)}")
    args = [str(a) for a in args]
    for a in args:
        if a.split("=", 1)[0] in SWEEP_OPTIONS:
            raise _fail(spec, f"{where}.args", f"{a.split('=', 1)[0]} is set by the sweep itself")
    return LogSpec(name=name, path=path, joint=joint, odometry=odometry, ground_truth=gt, relations=relations,
                   time_offset=float(time_offset), args=tuple(args))


def _seeds(spec: Path, value: Any) -> tuple[int, ...]:
    if isinstance(value, dict):
        seeds = expand_range(spec, "seeds", value, integer=True)
    elif isinstance(value, list):
        seeds = value
    elif isinstance(value, int) and not isinstance(value, bool):
        seeds = [value]
    else:
        raise _fail(spec, "seeds", f"must be a list of seeds or a range {{from: A, to: B}}, not {_shown(value)}")
    if not seeds:
        raise _fail(spec, "seeds", "no seeds")
    for s in seeds:
        if not isinstance(s, int) or isinstance(s, bool) or s < 0:
            raise _fail(spec, "seeds", f"a seed must be a non-negative integer, not {_shown(s)}")
    if len(set(seeds)) != len(seeds):
        raise _fail(spec, "seeds", "a seed is listed twice")
    return tuple(seeds)


def _config_value(cfg: Any, key: str) -> Any:
    """The value at a dotted ``key`` of ``cfg`` as written in files (modes as strings)."""
    from enum import Enum

    value = cfg
    for part in key.split("."):
        value = getattr(value, part)
    return value.value if isinstance(value, Enum) else value


def _settings(spec: Path, value: Any) -> dict[str, tuple[Any, ...]]:
    from pfslam.config import SlamConfig, with_values

    if value is None:
        return {}
    if not isinstance(value, dict):
        raise _fail(spec, "settings", f"must be a mapping of config keys to lists of values, not {_shown(value)}")
    out: dict[str, tuple[Any, ...]] = {}
    base = SlamConfig()
    for key, values in value.items():
        where = f"settings.{key}"
        if not isinstance(key, str):
            raise _fail(spec, "settings", f"a key must be a config key (a string), not {_shown(key)}")
        if key == "seed":
            raise _fail(spec, where, "the seed of each run comes from 'seeds'")
        if isinstance(values, dict):
            values = expand_range(spec, where, values)
        elif not isinstance(values, list):
            values = [values]
        if not values:
            raise _fail(spec, where, "no values")
        canonical = []
        for v in values:
            try:
                cfg = with_values(base, {key: v})
            except ConfigError as e:
                raise _fail(spec, where, str(e)) from None
            canonical.append(_config_value(cfg, key))
        if len(set(map(repr, canonical))) != len(canonical):
            raise _fail(spec, where, "a value is listed twice")
        out[key] = tuple(canonical)
    return out


def parse_spec(data: Any, spec: Path) -> Spec:
    """Validate a spec's YAML data (``spec``: its file, for relative paths and messages)."""
    from pfslam.config import SlamConfig, slam_values, with_values

    spec = Path(os.path.normpath(Path(spec).absolute()))
    if not isinstance(data, dict):
        raise InputError(spec, f"a sweep spec is a mapping with {', '.join(SPEC_KEYS)}, not {_shown(data)}")
    unknown = [k for k in data if k not in SPEC_KEYS]
    if unknown:
        raise _fail(spec, str(unknown[0]), f"unknown key (a spec has {', '.join(SPEC_KEYS)})")
    logs_data = data.get("logs")
    if not isinstance(logs_data, list) or not logs_data:
        raise _fail(spec, "logs", "needs a list of logs (each with a name and a path)")
    logs = tuple(_log_spec(spec, i, entry) for i, entry in enumerate(logs_data))
    names = [log.name for log in logs]
    for n in names:
        if names.count(n) > 1:
            raise _fail(spec, "logs", f"the name {n!r} is used twice")
    seeds = _seeds(spec, data.get("seeds", [0]))
    settings = _settings(spec, data.get("settings"))
    out = Spec(path=spec, logs=logs, seeds=seeds, settings=settings)
    if out.runs > MAX_RUNS:
        raise _fail(spec, "settings", f"the grid has {out.runs} runs (at most {MAX_RUNS})")
    for combo in out.combinations():  # values valid one by one may still clash
        try:
            with_values(SlamConfig(), slam_values(combo))
        except ConfigError as e:
            raise _fail(spec, "settings", f"{settings_slug(combo)}: {e}") from None
    return out


def load_spec(path: str | Path) -> Spec:
    """Read and validate a spec file; InputError naming the file and the key otherwise."""
    p = Path(path)
    if p.is_dir():
        raise InputError(p, "is a folder, not a sweep spec")
    if not p.is_file():
        raise InputError(p, "sweep spec not found")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as e:
        raise InputError(p, f"not UTF-8 text (byte {e.object[e.start]:#04x} at offset {e.start})") from None
    except yaml.YAMLError as e:
        raise InputError(p, f"not valid YAML ({str(e).splitlines()[0]})") from None
    return parse_spec(data, p)


# -- the grid ------------------------------------------------------------------------------


def _value_text(v: Any) -> str:
    if hasattr(v, "item") and not isinstance(v, (str, bytes)):  # a NumPy scalar from a table
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def settings_text(values: dict[str, Any]) -> str:
    """``particles=20, local_search.enabled=false`` (``defaults`` without settings)."""
    return ", ".join(f"{k}={_value_text(v)}" for k, v in values.items()) or "defaults"


def settings_slug(values: dict[str, Any]) -> str:
    """A folder name for a setting combination: ``particles=20,local_search.enabled=false``
    (``default`` without settings); characters unsafe in file names become ``_``."""
    if not values:
        return "default"
    text = ",".join(f"{k}={_value_text(v)}" for k, v in values.items())
    slug = re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)
    if slug != text or len(slug) > 120:  # keep distinct combinations apart after the clean-up
        slug = f"{slug[:100]}~{hashlib.sha1(text.encode()).hexdigest()[:8]}"
    return slug


@dataclass(frozen=True)
class Job:
    """Everything one run needs, and nothing else (this is what goes to a worker)."""

    log: str
    path: str
    joint: str | None
    odometry: str
    ground_truth: str | None
    relations: str | None
    time_offset: float
    args: tuple[str, ...]
    settings: dict[str, Any]
    seed: int
    out_dir: str  # the sweep's folder
    run_dir: str  # relative to out_dir: runs/<log>/<slug>/seed<k>
    timeout: float | None = None
    stop_file: str | None = None  # once this file exists the run is stopped (and leaves no row)

    @property
    def folder(self) -> Path:
        return Path(self.out_dir) / self.run_dir

    @property
    def fingerprint(self) -> str:
        """What makes a run the same run: its inputs, settings and seed (not where it is
        written, nor its time limit)."""
        ident = {k: v for k, v in asdict(self).items() if k not in ("out_dir", "run_dir", "timeout", "stop_file")}
        return hashlib.sha1(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()

    def command(self) -> list[str]:
        """The ``pfslam slam`` command line of this run."""
        folder = self.folder
        cmd = [sys.executable, "-m", "pfslam.cli", "slam", self.path, "--config", str(folder / CONFIG_FILE),
               "--seed", str(self.seed), "-o", str(folder)]
        if self.joint:
            cmd += ["-j", self.joint]
        cmd += ["--odometry", self.odometry]
        if self.ground_truth:
            cmd += ["-g", self.ground_truth]
        return cmd + list(self.args)


def make_jobs(spec: Spec, out_dir: str | Path, timeout: float | None = None) -> list[Job]:
    """One job per log × setting combination × seed, in that order."""
    out = str(Path(os.path.normpath(Path(out_dir).absolute())))
    jobs = []
    for log in spec.logs:
        for combo in spec.combinations():
            slug = settings_slug(combo)
            for seed in spec.seeds:
                jobs.append(Job(
                    log=log.name, path=str(log.path), joint=str(log.joint) if log.joint else None,
                    odometry=log.odometry.replace("{seed}", str(seed)),
                    ground_truth=str(log.ground_truth) if log.ground_truth else None,
                    relations=str(log.relations) if log.relations else None, time_offset=log.time_offset,
                    args=log.args, settings=dict(combo), seed=seed, out_dir=out,
                    run_dir=f"runs/{log.name}/{slug}/seed{seed}", timeout=timeout,
                ))
    return jobs


# -- one run -------------------------------------------------------------------------------


def _nan_to_none(v: Any) -> Any:
    return None if isinstance(v, float) and not math.isfinite(v) else v


def _row(job: Job, **values: Any) -> dict[str, Any]:
    """A result row: the job's identity, every metric (None where unknown), then ``values``."""
    row: dict[str, Any] = {"log": job.log, "seed": job.seed, "settings": dict(job.settings), "status": "error",
                           "exit_code": None, "message": ""}
    row.update({m: None for m in METRICS})
    row.update(run_dir=job.run_dir, fingerprint=job.fingerprint)
    row.update(values)
    return {k: _nan_to_none(v) for k, v in row.items()}


def write_row(job: Job, row: dict[str, Any]) -> None:
    """Write ``row`` as the run's ``result.json`` (atomically: the run is done once it is there)."""
    folder = job.folder
    row = {**row, "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    tmp = folder / f".{RESULT_FILE}.{os.getpid()}.tmp"
    tmp.write_text(json.dumps(row, indent=1, allow_nan=False))
    os.replace(tmp, folder / RESULT_FILE)


def failed_row(job: Job, status: str, message: str) -> dict[str, Any]:
    """The row of a run that never reported back (its worker was lost, the task failed)."""
    return _row(job, status=status, message=message)


def load_row(job: Job) -> dict[str, Any] | None:
    """The row a finished run left in its folder, or None if there is none (or it belongs to
    another job: a spec changed under the same names)."""
    try:
        row = json.loads((job.folder / RESULT_FILE).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or row.get("fingerprint") != job.fingerprint or row.get("status") not in STATUSES:
        return None
    row["run_dir"] = job.run_dir
    return row


def _message(stderr: str, code: int) -> str:
    """The run's own error line (``error: ...``), else the last line it printed."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    errors = [ln[len("error:"):].strip() for ln in lines if ln.startswith("error:")]
    text = errors[-1] if errors else lines[-1] if lines else f"exit code {code}"
    return text if len(text) <= 500 else text[:497] + "..."


def _signal_name(sig: int) -> str:
    try:
        return signal.Signals(sig).name
    except ValueError:
        return f"signal {sig}"


class SweepError(Exception):
    """The cluster failed the sweep as a whole (not one run)."""


class SweepStopped(Exception):
    """The sweep was stopped (its stop file appeared) while this run was going: no row."""


def _wait(pid: int, timeout: float | None, stop_file: str | None = None) -> tuple[int, Any, bool]:
    """Wait for the child ``pid`` (``os.wait4``: its own resource usage); past ``timeout``
    seconds, kill it. Returns (wait status, rusage, timed out). If ``stop_file`` appears
    (checked every second) the child is killed and SweepStopped raised. The child is killed
    only while it is known not to be reaped, so a recycled pid is never hit."""
    deadline = None if timeout is None else time.monotonic() + timeout
    timed_out = stopped = False
    try:
        fd = os.pidfd_open(pid)  # Linux: a file descriptor that becomes readable when the child ends
    except (AttributeError, OSError):
        fd = None
    try:
        while True:
            wpid, status, usage = os.wait4(pid, os.WNOHANG)
            if wpid == pid:
                if stopped:
                    raise SweepStopped(stop_file)
                return status, usage, timed_out
            if not (stopped or timed_out):
                if stop_file is not None and os.path.exists(stop_file):
                    os.kill(pid, signal.SIGKILL)
                    stopped = True
                    continue
                if deadline is not None and time.monotonic() >= deadline:
                    os.kill(pid, signal.SIGKILL)
                    timed_out = True
                    continue
            left = 1.0 if deadline is None or timed_out or stopped else min(1.0, max(0.0, deadline - time.monotonic()))
            if fd is not None:
                select.select([fd], [], [], left)
            else:
                time.sleep(min(left, 0.05))
    finally:
        if fd is not None:
            os.close(fd)


def _metrics(job: Job) -> tuple[dict[str, Any], str]:
    """The figures of a finished run from its run.json (and its relations), and a note on
    what could not be read ("" if nothing)."""
    folder = job.folder
    out: dict[str, Any] = {}
    notes = []
    try:
        info = json.loads((folder / "run.json").read_text())
    except (OSError, ValueError) as e:
        return out, f"no run.json ({e.__class__.__name__})"
    metrics = info.get("metrics") or {}
    slam = metrics.get("SLAM") or {}
    agree = metrics.get("map_agreement") or {}
    out.update(
        ate_raw=slam.get("ate_rmse"), ate_aligned=slam.get("ate_rmse_aligned"),
        heading_rmse_deg=slam.get("heading_rmse_deg"), rpe_trans=slam.get("rpe_trans_rmse"),
        map_agreement=agree.get("SLAM"), odometry_map_agreement=agree.get("odometry"),
        scans=info.get("scans_processed"), scans_per_s=info.get("scans_per_second"),
        real_time_factor=info.get("real_time_factor"),
    )
    if job.relations:
        from pfslam.evaluate import read_relations, relation_errors
        from pfslam.io.trajectory import read_tum

        try:
            t, poses = read_tum(folder / "trajectory.tum")
            r = relation_errors(t, poses, read_relations(job.relations), time_offset=job.time_offset)
            out.update(relations_trans=r.trans_mean, relations_rot_deg=r.rot_mean_deg, relations_count=r.matched)
            if r.matched == 0:
                notes.append(f"relations: none matched ({r.skipped} skipped; check time_offset)")
        except Exception as e:  # a broken trajectory must not lose the row
            notes.append(f"relations: {e}")
    return out, "; ".join(notes)


def _max_rss_mb(usage: Any) -> float:
    """``ru_maxrss`` in MB: Linux reports KiB, macOS bytes."""
    kib = usage.ru_maxrss / 1024 if sys.platform == "darwin" else usage.ru_maxrss
    return kib / 1024


def child_env() -> dict[str, str]:
    """The environment of a run: this one, one thread per library, no progress bars."""
    env = dict(os.environ)
    env.update(THREAD_ENV)
    env.pop("PFSLAM_PROGRESS", None)
    env.setdefault("COLUMNS", "200")
    return env


def _die_with_parent_fn() -> Callable[[], None] | None:
    """On Linux, a function for ``preexec_fn`` that has the child killed when the thread that
    started it ends (``PR_SET_PDEATHSIG``): a worker that goes away (the sweep was stopped,
    the cluster shut down) takes its run with it instead of leaving it running unwatched."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    parent = os.getpid()

    def die_with_parent() -> None:
        prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        if os.getppid() != parent:  # the parent went away before the line above
            os._exit(1)

    return die_with_parent


def run_job(job: Job) -> dict[str, Any]:
    """Run one job: write its config, execute ``pfslam slam`` in a fresh subprocess (output
    in the run folder, stdout/stderr in stdout.txt/stderr.txt), wait for it (killing it after
    ``job.timeout`` s), read its figures, write ``result.json`` and return the row.

    Status: ``ok`` (exit 0), ``error`` (another exit code: the run's own error line is the
    message), ``killed`` (ended by a signal from outside, or interrupted), ``timeout``."""
    from pfslam.config import SlamConfig, dump_sections, slam_values, with_values

    if job.stop_file is not None and os.path.exists(job.stop_file):
        raise SweepStopped(job.stop_file)
    folder = job.folder
    folder.mkdir(parents=True, exist_ok=True)
    for name in _STALE:
        with contextlib.suppress(FileNotFoundError):
            (folder / name).unlink()
    (folder / CONFIG_FILE).write_text(dump_sections(with_values(SlamConfig(), slam_values(job.settings))))
    cmd = job.command()
    t0 = time.perf_counter()
    with open(folder / STDOUT_FILE, "wb") as out, open(folder / STDERR_FILE, "wb") as err:
        # A session of its own: Ctrl-C in the terminal is the sweep's to handle, not the run's.
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=err, env=child_env(),
                                start_new_session=True, preexec_fn=_die_with_parent_fn())
        try:
            hook = os.environ.get(TEST_KILL_ENV)
            if hook and hook in str(folder):
                os.kill(proc.pid, signal.SIGKILL)
            status, usage, timed_out = _wait(proc.pid, job.timeout, job.stop_file)
        except BaseException:  # the worker is going away: the run goes with it
            with contextlib.suppress(OSError):
                os.kill(proc.pid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                os.waitpid(proc.pid, 0)
            raise
    seconds = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    proc.returncode = code  # reaped here (wait4): Popen must not wait for it again
    stderr = (folder / STDERR_FILE).read_text(errors="replace")
    if timed_out:
        result, message = "timeout", f"killed after the time limit of {job.timeout:g} s"
    elif code < 0:
        result, message = "killed", f"killed by {_signal_name(-code)}"
    elif code == 130:
        result, message = "killed", "interrupted (SIGINT)"
    elif code != 0:
        result, message = "error", _message(stderr, code)
    else:
        result, message = "ok", ""
    figures, note = _metrics(job)
    if result == "ok" and note:
        message = note
    row = _row(job, status=result, exit_code=code, message=message, peak_rss_mb=_max_rss_mb(usage),
               seconds=seconds, **figures)
    write_row(job, row)
    return row


# -- many runs -----------------------------------------------------------------------------


def plan(jobs: Sequence[Job], retry_failed: bool = False) -> tuple[dict[str, dict[str, Any]], list[Job]]:
    """The rows of the jobs already done (by run folder) and the jobs still to run. With
    ``retry_failed`` the runs that ended in error, killed or timeout are run again."""
    done: dict[str, dict[str, Any]] = {}
    todo = []
    for job in jobs:
        row = load_row(job)
        if row is not None and not (retry_failed and row["status"] != "ok"):
            done[job.run_dir] = row
        else:
            todo.append(job)
    return done, todo


def cpu_count() -> int:
    """The CPUs this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _connect(scheduler: str) -> Any:
    from dask.distributed import Client

    kwargs = {"scheduler_file": scheduler} if os.path.isfile(scheduler) else {"address": scheduler}
    try:
        return Client(timeout="20s", **kwargs)
    except (OSError, TimeoutError, ValueError) as e:
        raise InputError("--scheduler", f"cannot connect to {scheduler} ({e})") from None


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while worker processes start, so that they (and the runs they start)
    inherit it ignored: Ctrl-C in the terminal reaches only the sweep, which stops them."""
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None) -> Iterator[Any]:
    """A Dask client: of an existing scheduler (an address, or a scheduler file), or of a
    new local cluster of ``workers`` processes (default: one per CPU) with one thread each."""
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        client = _connect(scheduler)
        logging.disable(logging.ERROR)  # a lost scheduler is reported once, by the caller, not as tracebacks
        try:
            yield client
        finally:
            with contextlib.suppress(Exception):
                client.close(timeout=10)
            logging.disable(logging.NOTSET)
        return
    n = workers or cpu_count()
    # A run that takes its worker down is a lost run (recorded as killed), not retried; a
    # worker holds only the run it is running (no queue that its loss would take along).
    with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0}), _sigint_ignored():
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None, silence_logs=logging.CRITICAL)
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def run_jobs(jobs: Sequence[Job], client: Any, on_result: Callable[[dict[str, Any]], None] | None = None,
             ) -> list[dict[str, Any]]:
    """Run ``jobs`` on the Dask ``client``'s cluster, one task per job, and return their rows
    in the order they finish (each also passed to ``on_result`` as it arrives). A task that
    failed without a row (its worker was lost: ``KilledWorker``; an error in the runner)
    gets a ``killed`` / ``error`` row. On any exception (Ctrl-C) the runs are stopped: the
    queued ones cancelled, the running ones killed within a second through a stop file in the
    sweep's folder (which every worker sees), none of them leaving a row; the exception goes on."""
    from dataclasses import replace

    from dask.distributed import as_completed
    from distributed.scheduler import KilledWorker

    for out in {job.out_dir for job in jobs}:  # the stop files of earlier sweeps
        for old in Path(out).glob(".stop-*"):
            with contextlib.suppress(OSError):
                old.unlink()
    tag = uuid.uuid4().hex[:8]
    stop_files = {str(Path(job.out_dir) / f".stop-{tag}") for job in jobs}
    jobs = [replace(job, stop_file=str(Path(job.out_dir) / f".stop-{tag}")) for job in jobs]
    futures = {client.submit(run_job, job, key=f"pfslam-sweep-{tag}-{i}", pure=False, retries=0): job
               for i, job in enumerate(jobs)}
    rows = []
    lost = 0
    try:
        for fut in as_completed(futures):
            job = futures[fut]
            if fut.status == "finished":
                row = fut.result()
            elif fut.status == "error":
                exc = fut.exception()
                if isinstance(exc, KilledWorker):
                    row = failed_row(job, "killed", "the Dask worker running it was lost")
                else:
                    row = failed_row(job, "error", f"{type(exc).__name__}: {exc}"[:500])
                with contextlib.suppress(OSError):
                    write_row(job, row)
            else:  # cancelled by the cluster (its scheduler went away): not run, no row
                lost += 1
                continue
            rows.append(row)
            if on_result is not None:
                on_result(row)
        if lost:
            raise SweepError(f"the cluster cancelled {lost} runs (was its scheduler lost?)")
    except BaseException:
        for f in stop_files:
            with contextlib.suppress(OSError):
                Path(f).touch()
        with contextlib.suppress(Exception):
            client.cancel(list(futures), force=True)
        raise
    return rows


# -- the table, the summary, the picture ---------------------------------------------------


def build_table(rows: Sequence[dict[str, Any]], setting_keys: Sequence[str]) -> pd.DataFrame:
    """One row per run: log, seed, one column per setting, status, exit code, message, the
    metrics, run folder (relative to the sweep's folder)."""
    import pandas as pd

    columns = [*HEAD_COLUMNS, *setting_keys, *STATUS_COLUMNS, *METRICS, *TAIL_COLUMNS]
    records = []
    for row in rows:
        rec = {c: row.get(c) for c in columns}
        for k in setting_keys:
            rec[k] = (row.get("settings") or {}).get(k)
        records.append(rec)
    df = pd.DataFrame.from_records(records, columns=columns)
    for m in METRICS:
        df[m] = pd.to_numeric(df[m], errors="coerce").astype("Int64" if m in COUNT_METRICS else "float64")
    df["seed"] = df["seed"].astype("int64")
    df["exit_code"] = df["exit_code"].astype("Int64")
    for c in ("log", "status", "message", "run_dir"):
        df[c] = df[c].astype("string")
    df["message"] = df["message"].fillna("")
    for k in setting_keys:  # a setting column holds values of one type (the config field's)
        values = [v for v in df[k] if v is not None]
        if values and all(isinstance(v, bool) for v in values):
            df[k] = df[k].astype("boolean")
        elif values and all(isinstance(v, str) for v in values):
            df[k] = df[k].astype("string")
    return df


def write_table(df: pd.DataFrame, out_dir: str | Path) -> tuple[Path, Path]:
    """``results.csv`` and ``results.parquet`` in ``out_dir`` (written atomically)."""
    out = Path(out_dir)
    csv, parquet = out / "results.csv", out / "results.parquet"
    for path, write in ((csv, lambda p: df.to_csv(p, index=False)),
                        (parquet, lambda p: df.to_parquet(p, index=False, engine="pyarrow"))):
        tmp = path.with_name(f".{path.name}.tmp")
        write(tmp)
        os.replace(tmp, path)
    return csv, parquet


def summarize(df: pd.DataFrame, setting_keys: Sequence[str]) -> pd.DataFrame:
    """Per log × setting combination (in the table's order): runs, ok and failed counts, and
    the median, min and max over the ok runs of each of :data:`SUMMARY_METRICS`
    (columns ``<metric>_median``, ``_min``, ``_max``; NaN without ok runs)."""
    import pandas as pd

    keys = ["log", *setting_keys]
    records = []
    for group, part in df.groupby(keys, sort=False, dropna=False):
        group = group if isinstance(group, tuple) else (group,)
        ok = part[part["status"] == "ok"]
        rec: dict[str, Any] = dict(zip(keys, group))
        rec.update(runs=len(part), ok=len(ok), failed=len(part) - len(ok))
        for m in SUMMARY_METRICS:
            v = ok[m].dropna()
            rec[f"{m}_median"] = float(v.median()) if len(v) else float("nan")
            rec[f"{m}_min"] = float(v.min()) if len(v) else float("nan")
            rec[f"{m}_max"] = float(v.max()) if len(v) else float("nan")
        records.append(rec)
    return pd.DataFrame.from_records(records)


def combination_label(rec: dict[str, Any] | Any, setting_keys: Sequence[str]) -> str:
    """``log`` or ``log: key=value, ...`` for a row of the table or of the summary."""
    values = {k: rec[k] for k in setting_keys}
    return f"{rec['log']}: {settings_text(values)}" if values else str(rec["log"])


def plot_summary(df: pd.DataFrame, setting_keys: Sequence[str], path: str | Path) -> Path | None:
    """A box plot per metric (of :data:`SUMMARY_METRICS` that any ok run has), one box per
    log × setting combination over the seeds; None (and no file) without ok runs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = df[df["status"] == "ok"]
    metrics = [m for m in SUMMARY_METRICS if ok[m].notna().any()]
    if not metrics:
        with contextlib.suppress(FileNotFoundError):  # not the picture of an earlier table
            Path(path).unlink()
        return None
    keys = ["log", *setting_keys]
    groups = [(dict(zip(keys, g if isinstance(g, tuple) else (g,))), part)
              for g, part in ok.groupby(keys, sort=False, dropna=False)]
    labels = [combination_label(g, setting_keys).replace(": ", "\n").replace(", ", "\n") for g, _ in groups]
    ncols = min(3, len(metrics))
    nrows = -(-len(metrics) // ncols)
    longest = max(len(line) for label in labels for line in label.splitlines())
    width = max(4.0, max(1.0, 0.065 * longest + 0.2) * len(groups) + 1.0)  # room for the 7 pt labels
    fig, axes = plt.subplots(nrows, ncols, figsize=(ncols * width, nrows * 4.2), squeeze=False)
    for ax, m in zip(axes.flat, metrics):
        data = [part[m].dropna().to_numpy() for _, part in groups]
        pos = [i + 1 for i, d in enumerate(data) if len(d)]
        ax.boxplot([d for d in data if len(d)], positions=pos, widths=0.6, showfliers=False)
        for p, d in zip(pos, [d for d in data if len(d)]):  # every run, outliers included
            ax.scatter([p] * len(d), d, s=10, color="tab:blue", alpha=0.6, zorder=3)
        ax.set_xticks(range(1, len(groups) + 1))
        ax.set_xticklabels(labels, fontsize=7, rotation=90 if len(groups) > 8 else 0, ha="center")
        ax.set_xlim(0.4, len(groups) + 0.6)
        ax.set_title(METRIC_LABELS.get(m, m))
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(metrics):]:
        ax.set_visible(False)
    fig.suptitle(f"pfslam sweep: {len(ok)} ok runs, boxes over seeds")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
