"""What the command line shows: progress bars, tables, the printer a run reports to, and the
closing report of a run."""

from __future__ import annotations

import contextlib
import os
import time
from typing import TYPE_CHECKING, Callable, ContextManager, Iterator, TypeVar

import numpy as np
import typer
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from pfslam.cli.app import err_console, error, out_console, received_signals, warn
from pfslam.eval.table import METRICS

if TYPE_CHECKING:
    from pfslam.eval.metrics import TrajectoryErrors
    from pfslam.pipeline import Outcome, Scores
    from pfslam.tools.calibrate import Calibration

R = TypeVar("R")


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:>7.1f} {task.fields[unit]}/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=err_console,
        transient=False,
        disable=not err_console.is_terminal and "PFSLAM_PROGRESS" not in os.environ,
    )


@contextlib.contextmanager
def _progress_bars(bars: list[tuple[str, int, str]]) -> Iterator[list[Callable[[int, int], None]]]:
    """Progress bars on stderr, one per (label, total, unit counted), and the (done, total)
    callbacks that move them."""
    with _progress() as prog:
        t0 = time.perf_counter()

        def mover(task: TaskID) -> Callable[[int, int], None]:
            def cb(i: int, n: int) -> None:
                dt = time.perf_counter() - t0
                prog.update(task, total=n, completed=i, rate=i / dt if dt > 0 else 0.0)

            return cb

        yield [mover(prog.add_task(label, total=total, rate=0.0, unit=unit)) for label, total, unit in bars]


def errors_table(rows: dict[str, TrajectoryErrors]) -> Table:
    tab = Table(show_header=True, header_style="bold")
    tab.add_column("trajectory", no_wrap=True, overflow="fold")  # a file name whole, never "trajectory.t..."
    shown = [METRICS[m] for m in ("ate_raw", "ate_aligned", "heading_rmse_deg", "rpe_trans")]
    for m in shown:
        tab.add_column(m.heading, justify="right")
    for name, e in rows.items():
        values = (e.ate_rmse, e.ate_rmse_aligned, e.heading_rmse_deg, e.rpe_trans_rmse)
        tab.add_row(name, *(m.show(v) for m, v in zip(shown, values)))
    return tab


def calibration_table(cal: Calibration) -> Table:
    tab = Table(show_header=True, header_style="bold")
    tab.add_column("quantity")
    tab.add_column("value", justify="right")
    tab.add_row("translation scale", f"{cal.trans_scale:.3f}")
    tab.add_row("rotation scale", f"{cal.rot_scale:.3f}")
    tab.add_row("scan latency (s)", f"{cal.scan_latency:+.3f}")
    tab.add_row(
        "heading residual per scan (deg), before -> after",
        f"{cal.rot_residual_deg_uncalibrated:.2f} -> {cal.rot_residual_deg:.2f}",
    )
    tab.add_row("translation residual per scan (m)", f"{cal.trans_residual:.4f}")
    tab.add_row("scan pairs matched / used", f"{cal.pairs_matched} / {cal.pairs_used}")
    return tab


class Printer:
    """The pipeline's reporter for a terminal: results on stdout, the rest on stderr."""

    def warn(self, text: str) -> None:
        warn(text)

    def say(self, text: str) -> None:
        out_console.print(escape(text), soft_wrap=True)

    def note(self, text: str) -> None:
        err_console.print(escape(text), highlight=False, soft_wrap=True)

    def calibration(self, cal: Calibration) -> None:
        out_console.print(calibration_table(cal))

    def scores(self, scores: Scores) -> None:
        if scores.errors:
            out_console.print(errors_table(scores.errors))
        if scores.map_agreement:
            shown = ", ".join(
                f"{k} {METRICS['map_agreement'].show(v)}"
                if np.isfinite(v)
                else f"{k} - (no later scan re-observes its map, or it spans more than the largest map)"
                for k, v in scores.map_agreement.items()
            )
            out_console.print(
                f"map agreement (later scans on the walls earlier scans mapped, within 0.1 m): {shown}", soft_wrap=True
            )

    def progress(self, bars: list[tuple[str, int, str]]) -> ContextManager[list[Callable[[int, int], None]]]:
        return _progress_bars(bars)


def run_with_progress(label: str, total: int, fn: Callable[[Callable[[int, int], None]], R]) -> R:
    with _progress_bars([(label, total, "scans")]) as (cb,):
        return fn(cb)


def report(outcome: Outcome) -> None:
    """Say how a run whose results were written ended; the exit code for one stopped early."""
    run = outcome.run
    received_signals().extend(outcome.signals)
    if run.error is not None:
        error(f"{outcome.log}: {run.error}; the results for the {run.scans} scans before it are in {outcome.out}/")
        raise typer.Exit(2)
    if run.interrupted:
        err_console.print(
            f"[yellow]interrupted:[/] results for the {run.scans} scans done are in {escape(str(outcome.out))}/",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(130)
    out_console.print(escape(outcome.summary()), soft_wrap=True)
