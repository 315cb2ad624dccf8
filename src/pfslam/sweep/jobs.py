"""A sweep's jobs: :class:`Job`, everything one run needs (its command line, its folder, what
makes it the same run as an earlier one), the files of its folder, and :func:`make_jobs`, one
job per log × setting combination × seed of a :class:`~pfslam.sweep.spec.Spec`
(see :mod:`pfslam.sweep`). Nothing here prints."""

from __future__ import annotations

import hashlib
import json
import os
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pfslam.sweep.spec import Spec, settings_slug

if TYPE_CHECKING:
    from pfslam.config import ConfigValue

RESULT_FILE = "result.json"
CONFIG_FILE = "sweep_config.yaml"
STDOUT_FILE = "stdout.txt"
STDERR_FILE = "stderr.txt"
# Files of an earlier attempt that must not be mistaken for this attempt's results.
STALE_FILES = (RESULT_FILE, "run.json", "trajectory.tum")


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
    settings: dict[str, ConfigValue]
    seed: int
    out_dir: str  # the sweep's folder
    run_dir: str  # relative to out_dir: runs/<log>/<slug>/seed<k>
    timeout: float | None = None
    stop_file: str | None = None  # once this file exists the run is stopped (and leaves no row)
    run: str = "slam"  # the pfslam command: slam or localize
    map: str | None = None  # localize: --map

    @property
    def folder(self) -> Path:
        return Path(self.out_dir) / self.run_dir

    @property
    def fingerprint(self) -> str:
        """What makes a run the same run: its inputs, settings and seed (not where it is
        written, nor its time limit)."""
        ident = {k: v for k, v in asdict(self).items() if k not in ("out_dir", "run_dir", "timeout", "stop_file")}
        if self.run == "slam":  # a slam run's as before localize runs: the runs of earlier sweeps stay done
            del ident["run"], ident["map"]
        return hashlib.sha1(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()

    def command(self) -> list[str]:
        """The ``pfslam slam`` (or ``pfslam localize``) command line of this run."""
        folder = self.folder
        cmd = [
            sys.executable,
            "-m",
            "pfslam.cli",
            self.run,
            self.path,
            "--config",
            str(folder / CONFIG_FILE),
            "--seed",
            str(self.seed),
            "-o",
            str(folder),
        ]
        if self.map:
            cmd += ["--map", self.map]
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
                jobs.append(
                    Job(
                        log=log.name,
                        path=str(log.path).replace("{seed}", str(seed)),
                        joint=str(log.joint).replace("{seed}", str(seed)) if log.joint else None,
                        odometry=log.odometry.replace("{seed}", str(seed)),
                        ground_truth=str(log.ground_truth).replace("{seed}", str(seed)) if log.ground_truth else None,
                        relations=str(log.relations) if log.relations else None,
                        time_offset=log.time_offset,
                        args=log.args,
                        settings=dict(combo),
                        seed=seed,
                        out_dir=out,
                        run_dir=f"runs/{log.name}/{slug}/seed{seed}",
                        timeout=timeout,
                        run=spec.run,
                        map=str(log.map).replace("{seed}", str(seed)) if log.map else None,
                    )
                )
    return jobs
