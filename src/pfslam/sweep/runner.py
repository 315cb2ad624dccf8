"""Running a sweep's jobs: one real ``pfslam slam`` (or ``localize``) subprocess per job, its row read back from
its run folder; many jobs on a Dask cluster (see :mod:`pfslam.sweep`). Nothing here prints."""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import select
import signal
import subprocess
import sys
import time
import uuid
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator, Sequence

from pfslam.errors import InputError
from pfslam.process import peak_rss_mb
from pfslam.sweep.columns import STATUSES, metric_columns
from pfslam.sweep.jobs import CONFIG_FILE, RESULT_FILE, STALE_FILES, STDERR_FILE, STDOUT_FILE, Job
from pfslam.sweep.spec import config_class
from pfslam.types import JSON, JSONObject

if TYPE_CHECKING:
    from resource import struct_rusage

    from distributed import Client

# A run is one single-threaded process: libraries must not start a thread per core each.
THREAD_ENV = {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

# -- one run -------------------------------------------------------------------------------


def _nan_to_none(v: JSON) -> JSON:
    return None if isinstance(v, float) and not math.isfinite(v) else v


def _row(job: Job, **values: JSON) -> JSONObject:
    """A result row: the job's identity, every metric of its kind of run (None where
    unknown), then ``values``."""
    row: JSONObject = {
        "log": job.log,
        "seed": job.seed,
        "settings": dict(job.settings),
        "status": "error",
        "exit_code": None,
        "message": "",
    }
    row.update({m: None for m in metric_columns(job.run)})
    row.update(run_dir=job.run_dir, fingerprint=job.fingerprint)
    row.update(values)
    return {k: _nan_to_none(v) for k, v in row.items()}


def write_row(job: Job, row: JSONObject) -> None:
    """Write ``row`` as the run's ``result.json`` (atomically: the run is done once it is there)."""
    folder = job.folder
    row = {**row, "finished_at": datetime.now(UTC).isoformat(timespec="seconds")}
    tmp = folder / f".{RESULT_FILE}.{os.getpid()}.tmp"
    tmp.write_text(json.dumps(row, indent=1, allow_nan=False))
    os.replace(tmp, folder / RESULT_FILE)


def failed_row(job: Job, status: str, message: str) -> JSONObject:
    """The row of a run that never reported back (its worker was lost, the task failed)."""
    return _row(job, status=status, message=message)


def load_row(job: Job) -> JSONObject | None:
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
    errors = [ln[len("error:") :].strip() for ln in lines if ln.startswith("error:")]
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


def _wait(pid: int, timeout: float | None, stop_file: str | None = None) -> tuple[int, struct_rusage, bool]:
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


def _metrics(job: Job) -> tuple[JSONObject, str]:
    """The figures of a finished run from its run.json (and its relations), and a note on
    what could not be read ("" if nothing). A slam run's accuracy is its ``metrics.SLAM``, a
    localize run's its ``metrics.estimate`` (and its ``filter`` section: settle, recoveries,
    fitted field width)."""
    folder = job.folder
    out: JSONObject = {}
    notes = []
    try:
        info = json.loads((folder / "run.json").read_text())
    except (OSError, ValueError) as e:
        return out, f"no run.json ({e.__class__.__name__})"
    metrics = info.get("metrics") or {}
    est = metrics.get("estimate" if job.run == "localize" else "SLAM") or {}
    agree = metrics.get("map_agreement") or {}
    out.update(
        ate_raw=est.get("ate_rmse"),
        ate_aligned=est.get("ate_rmse_aligned"),
        heading_rmse_deg=est.get("heading_rmse_deg"),
        rpe_trans=est.get("rpe_trans_rmse"),
        map_agreement=agree.get("SLAM"),
        odometry_map_agreement=agree.get("odometry"),
        scans=info.get("scans_processed"),
        scans_per_s=info.get("scans_per_second"),
        real_time_factor=info.get("real_time_factor"),
    )
    backend = info.get("backend")
    if job.run != "localize" and backend:
        edges = metrics.get("loop_edges") or {}
        out.update(
            backend_kept=int(bool(backend.get("kept"))),
            loops_solved=backend.get("loops_in_graph"),
            loops_off=edges.get("solved_off"),
            loops_found_off=edges.get("found_off"),
            loops_off_sure=edges.get("solved_off_beyond_own"),
            refused_gate=backend.get("refused_gate"),
            refused_spread=backend.get("refused_spread"),
            backend_s=backend.get("seconds"),
        )
    if job.run == "localize":
        flt = info.get("filter") or {}
        out.update(
            within_after_s=est.get("within_after_s"),  # None: it ended off the robot (or no truth)
            settle_s=(flt.get("settle") or {}).get("seconds"),  # None: it never settled
            recoveries=flt.get("recoveries"),
            sigma_hit=flt.get("sigma_hit"),  # only where the width was fitted
        )
        health = metrics.get("health") or {}
        in_state = health.get("seconds_in_state") or {}
        out.update(
            lost_s=in_state.get("lost"), degraded_s=in_state.get("degraded"), quality_min=health.get("lowest_quality")
        )
    if job.relations:
        from pfslam.eval.metrics import read_relations, relation_errors
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


def run_job(job: Job) -> JSONObject:
    """Run one job: write its config (the section of its kind of run), execute ``pfslam slam``
    or ``pfslam localize`` in a fresh subprocess (output in the run folder, stdout/stderr in
    stdout.txt/stderr.txt), wait for it (killing it after ``job.timeout`` s), read its
    figures, write ``result.json`` and return the row.

    Status: ``ok`` (exit 0), ``error`` (another exit code: the run's own error line is the
    message), ``killed`` (ended by a signal from outside, or interrupted), ``timeout``."""
    from pfslam.config import dump_sections, with_values

    if job.stop_file is not None and os.path.exists(job.stop_file):
        raise SweepStopped(job.stop_file)
    folder = job.folder
    folder.mkdir(parents=True, exist_ok=True)
    for name in STALE_FILES:
        with contextlib.suppress(FileNotFoundError):
            (folder / name).unlink()
    (folder / CONFIG_FILE).write_text(dump_sections(with_values(config_class(job.run)(), job.settings)))
    cmd = job.command()
    t0 = time.perf_counter()
    with open(folder / STDOUT_FILE, "wb") as out, open(folder / STDERR_FILE, "wb") as err:
        # A session of its own: Ctrl-C in the terminal is the sweep's to handle, not the run's.
        proc = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=err,
            env=child_env(),
            start_new_session=True,
            preexec_fn=_die_with_parent_fn(),
        )
        try:
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
    row = _row(
        job, status=result, exit_code=code, message=message, peak_rss_mb=peak_rss_mb(usage), seconds=seconds, **figures
    )
    write_row(job, row)
    return row


# -- many runs -----------------------------------------------------------------------------


def plan(jobs: Sequence[Job], retry_failed: bool = False) -> tuple[dict[str, JSONObject], list[Job]]:
    """The rows of the jobs already done (by run folder) and the jobs still to run. With
    ``retry_failed`` the runs that ended in error, killed or timeout are run again."""
    done: dict[str, JSONObject] = {}
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


def _connect(scheduler: str) -> Client:
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
def dask_client(workers: int | None = None, scheduler: str | None = None) -> Iterator[Client]:
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
    with (
        dask.config.set({"distributed.scheduler.allowed-failures": 0, "distributed.scheduler.worker-saturation": 1.0}),
        _sigint_ignored(),
    ):
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=logging.CRITICAL,
        )
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def run_jobs(
    jobs: Sequence[Job],
    client: Client,
    on_result: Callable[[JSONObject], None] | None = None,
) -> list[JSONObject]:
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
    futures = {
        client.submit(run_job, job, key=f"pfslam-sweep-{tag}-{i}", pure=False, retries=0): job
        for i, job in enumerate(jobs)
    }
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
