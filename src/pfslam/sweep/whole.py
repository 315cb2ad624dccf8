"""A whole sweep, as ``pfslam sweep`` runs it: plan (the spec's jobs, those already done), run
the rest on Dask keeping what is done when stopped, then the table, its summary and picture.
Nothing here prints: each finished run goes to a callback."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from pfslam.errors import PfslamError
from pfslam.io.folders import prepare_output_dir
from pfslam.process import interrupts_held
from pfslam.sweep import runner, table
from pfslam.sweep.jobs import Job, make_jobs
from pfslam.sweep.spec import Spec, load_spec
from pfslam.types import JSONObject

if TYPE_CHECKING:
    import pandas as pd


@dataclass
class Plan:
    """A sweep's jobs, the rows of those already done (by run folder) and those to run."""

    spec: Spec
    out: Path
    jobs: list[Job]
    rows: dict[str, JSONObject]
    todo: list[Job]

    @property
    def keys(self) -> list[str]:
        return list(self.spec.setting_keys)


@dataclass
class Result:
    """How a sweep ended: its table (every run with a row), the summary per setting
    combination, the files written, and whether it stopped early (Ctrl-C, a lost cluster)."""

    table: pd.DataFrame
    summary: pd.DataFrame
    csv: Path
    parquet: Path
    png: Path | None
    reported: set[str] = field(default_factory=set)  # run folders finished in this sweep
    interrupted: bool = False
    broken: str = ""  # why the cluster failed, if it did
    signals: list[int] = field(default_factory=list)  # stop signals held while the table was written

    @property
    def failed(self) -> pd.DataFrame:
        return self.table[self.table["status"] != "ok"]


def plan(spec_path: str | Path, out: str | Path, timeout: float | None = None, retry_failed: bool = False) -> Plan:
    """Read the spec, expand its jobs into ``out`` (made here), and find those already done."""
    spec = load_spec(spec_path)
    jobs = make_jobs(spec, out, timeout)
    prepare_output_dir(Path(out))
    rows, todo = runner.plan(jobs, retry_failed)
    return Plan(spec, Path(out), jobs, rows, todo)


def run(
    p: Plan,
    workers: int | None = None,
    scheduler: str | None = None,
    on_result: Callable[[JSONObject], None] | None = None,
) -> Result:
    """Run the plan's jobs to do on a local Dask cluster of ``workers`` processes (or the one at
    ``scheduler``), each row to ``on_result`` as it arrives; Ctrl-C or a failing cluster stop it
    with what is done kept. Then write the table (results.csv, .parquet) and summary.png."""
    reported: set[str] = set()
    interrupted, broken = False, ""

    def done(row: JSONObject) -> None:
        run_dir = str(row["run_dir"])  # the job's (runner._row)
        p.rows[run_dir] = row
        reported.add(run_dir)
        if on_result is not None:
            on_result(row)

    if p.todo:
        try:
            with runner.dask_client(workers, scheduler) as client:
                runner.run_jobs(p.todo, client, done)
        except KeyboardInterrupt:
            interrupted = True
        except PfslamError:
            raise
        except Exception as e:  # the cluster went away (scheduler lost, ...): keep what is done
            broken = f"the Dask cluster failed ({type(e).__name__}: {e}); the same command goes on from there"
    with interrupts_held() as got:
        df = table.build_table([p.rows[j.run_dir] for j in p.jobs if j.run_dir in p.rows], p.keys, p.spec.run)
        csv, parquet = table.write_table(df, p.out)
        summary = table.summarize(df, p.keys)
        png = table.plot_summary(df, p.keys, p.out / "summary.png")
    return Result(df, summary, csv, parquet, png, reported, interrupted or bool(got), broken, got)
