"""Fixtures shared by the test folders: simulated logs that take seconds to make are made
once per session, and so are the real-data runs several tests read; tests marked
``realdata`` skip (naming the folder) without the recordings."""

from __future__ import annotations

import os

# Under pytest-xdist each core already runs a test worker: Numba gets the cores per worker (one
# on this 2-core machine), in the worker and in the pfslam processes its tests start, instead of
# a thread per core in every process. Oversubscribed, the suite spent 617 CPU-s in 326 s; with
# one thread each, 363 CPU-s in 198 s. Set before anything imports Numba.
if "PYTEST_XDIST_WORKER_COUNT" in os.environ and "NUMBA_NUM_THREADS" not in os.environ:
    _workers = max(int(os.environ["PYTEST_XDIST_WORKER_COUNT"]), 1)
    os.environ["NUMBA_NUM_THREADS"] = str(max((os.cpu_count() or 1) // _workers, 1))

import fcntl  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402
from datafiles import DATA, need

from pfslam.config import SlamConfig
from pfslam.io.logs import load_log
from pfslam.pipeline import slam
from pfslam.tools.simulate import SimResult, simulate


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Without the data folder every ``realdata`` test is skipped with one reason; with it,
    each test still skips (through ``datafiles.need``) if its own recording is missing."""
    if DATA.is_dir():
        return
    skip = pytest.mark.skip(reason=f"real recordings not found in {DATA} (set PFSLAM_DATA to the data folder)")
    for item in items:
        if "realdata" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def office_sim(tmp_path_factory: pytest.TempPathFactory) -> SimResult:
    """Three minutes of a THOR humanoid walking the office loop (seed 0): odometry drifts
    more than 10 deg; the files (lidar, joint, ground truth, map.yaml) sit in one folder.
    Read-only: do not write into its folder."""
    return simulate("office", 180.0, seed=0, out_dir=tmp_path_factory.mktemp("office0"))


@pytest.fixture(scope="session")
def office_log(office_sim: SimResult):
    """``office_sim`` loaded as the CLI loads it (a LoadedLog: frames, format, warnings)."""
    return load_log(office_sim.lidar_path, office_sim.joint_path)


@pytest.fixture(scope="session")
def short_office(tmp_path_factory: pytest.TempPathFactory) -> SimResult:
    """Ten seconds (400 scans) of the office world (seed 3), with its true map.yaml next to
    the log: for command-line runs that must be quick. Read-only."""
    return simulate("office", 10.0, seed=3, out_dir=tmp_path_factory.mktemp("office3_10s"))


@pytest.fixture(scope="session")
def intel_single_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The output folder of Intel mapped as ``pfslam slam intel.gfs.log.gz --odometry
    synthetic:0 --filter single`` maps it (through :func:`pfslam.slam`, the call the command
    makes): map.yaml, trajectory.tum, odometry.tum, reference.tum, run.json. Read-only.

    The whole-log run takes 10-20 s, so it is made once per test session: under xdist, the
    first worker to ask makes it in the folder the workers share, and a worker asking
    meanwhile waits for it (the pattern of pytest-xdist's documentation)."""
    log = need("carmen/intel.gfs.log.gz")
    base = tmp_path_factory.getbasetemp()
    root = base.parent if "PYTEST_XDIST_WORKER" in os.environ else base
    out, done = root / "intel_single_map", root / "intel_single_map.done"
    with open(root / "intel_single_map.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        if not done.is_file():
            outcome = slam(log, out, odometry="synthetic:0", config=SlamConfig(filter="single"))
            assert outcome.run.error is None and not outcome.run.interrupted
            done.touch()
    return out
