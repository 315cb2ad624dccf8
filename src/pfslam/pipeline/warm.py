"""A first run compiles the filter's kernels (Numba; cached on disk after, so later runs load
them in a fraction of a second). Where the cache is cold, :class:`Warming` compiles them in
other processes, side by side, while this one prepares the log (corrects its odometry,
places a resumed session) or simulates the demo's, and says so if the filter must wait for
them; the filter then loads what they wrote."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from pfslam.config import SlamConfig, SlamFilter, resolve_filter
from pfslam.errors import ConfigError
from pfslam.pipeline.report import Reporter

COMPILING = "compiling the filter's kernels (first run only; later runs load them) ..."


def _dispatchers() -> list[Any]:
    """The largest of the filter's kernels: where their cache holds nothing for this source, so
    does the rest's."""
    from pfslam.kernels.refine import tiled_refine_kernel
    from pfslam.kernels.tiled import tiled_match_kernel, tiled_scan_update_kernel

    return [tiled_match_kernel, tiled_refine_kernel, tiled_scan_update_kernel]


def cold() -> bool:
    """Whether a kernel of the filter has nothing cached for its source as it is now (Numba's
    cache index is read; a cache Numba cannot be asked about counts as warm)."""
    try:
        return any(not d._cache._cache_file._load_index() for d in _dispatchers())
    except Exception:  # (another Numba's cache layout: say nothing rather than guess)
        return False


def _compile(part: int) -> None:
    from pfslam.filters.rbpf import load_kernels

    load_kernels(part)


class Warming:
    """Compiling the filter's kernels in other processes where the cache is cold (see the
    module notes), one per part of them (:data:`~pfslam.filters.rbpf.KERNEL_PARTS`), side by
    side; :meth:`wait` before the filter starts. (Fresh interpreters, not forks or spawns of
    this one: neither this process's threads nor a caller's script run twice.)"""

    def __init__(self, reporter: Reporter, config: SlamConfig) -> None:
        """``config``: the run's settings (a run of the single-map filter needs none of these)."""
        from pfslam.filters.rbpf import KERNEL_PARTS

        self._processes: list[subprocess.Popen[bytes]] = []
        self._reporter: Reporter | None = None
        try:
            rbpf = resolve_filter(config).filter is SlamFilter.RBPF
        except ConfigError:  # (refused later, where the run's config is made concrete, naming its file)
            return
        if not rbpf or not cold():
            return
        self._reporter = reporter
        here = str(Path(__file__).resolve().parents[2])  # (where this pfslam is imported from)
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")]))}
        try:
            for part in range(KERNEL_PARTS):
                child = f"from pfslam.pipeline.warm import _compile; _compile({part})"
                self._processes.append(
                    subprocess.Popen(
                        [sys.executable, "-c", child], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
                    )
                )
        except OSError:  # (no other process here: the filter compiles what is left itself)
            pass

    def wait(self) -> list[int]:
        """Until the other processes are done (their kernels on disk; what one failed to
        compile, the filter compiles itself), saying so while they are not. Returns their exit
        codes. (A run that stops before, on a log it cannot read, says nothing of them: they
        finish on their own, for the next run.)"""
        if self._reporter is not None and any(p.poll() is None for p in self._processes):
            self._reporter.note(COMPILING)
        codes = [p.wait() for p in self._processes]
        self._processes = []
        return codes
