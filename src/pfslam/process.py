"""The process around a run: what it costs (peak memory, measured one way wherever it is
reported: run.json, a sweep's table) and the stop signals held while results are written."""

from __future__ import annotations

import contextlib
import signal
import sys
from types import FrameType
from typing import TYPE_CHECKING, Callable, Iterator, Union

if TYPE_CHECKING:
    from resource import struct_rusage

# What signal.signal takes and gives back: a handler, SIG_DFL / SIG_IGN, or None (not set from Python).
Handler = Union[Callable[[int, FrameType | None], object], int, None]


def peak_rss_mb(usage: struct_rusage | None = None) -> float | None:
    """Peak resident memory in MB: of ``usage`` (a ``resource.struct_rusage``, e.g. a child's
    from ``os.wait4``), else of this process so far; None where the system does not tell it.
    ``ru_maxrss`` is in KiB on Linux and in bytes on macOS."""
    if usage is None:
        try:
            import resource

            usage = resource.getrusage(resource.RUSAGE_SELF)
        except (ImportError, OSError):
            return None
    kib = usage.ru_maxrss / 1024 if sys.platform == "darwin" else usage.ru_maxrss
    return float(kib) / 1024


@contextlib.contextmanager
def interrupts_held() -> Iterator[list[int]]:
    """Ctrl-C or SIGTERM while results are written is noted (the list fills), not acted on at
    once; outside the main thread nothing is held."""
    got: list[int] = []

    def hold(sig: int, frame: FrameType | None) -> None:
        got.append(sig)

    old: dict[int, Handler] = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, hold)
    except ValueError:  # not the main thread: nothing to hold
        yield got
        return
    try:
        yield got
    finally:
        for held, handler in old.items():
            signal.signal(held, handler)


def process_seconds() -> float | None:
    """Seconds since this process started (the interpreter's start and every import before
    now included), from /proc; None where the system does not tell it."""
    import os

    try:
        with open("/proc/self/stat") as f:
            start_ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return max(uptime - start_ticks / os.sysconf("SC_CLK_TCK"), 0.0)
    except (OSError, ValueError, IndexError, AttributeError):
        return None


def hand_back_freed() -> bool:
    """Hand the memory the C allocator holds freed back to the system (glibc's ``malloc_trim``),
    between steps that each free what they made: without, a later step's peak sits on top of
    an earlier one's freed heap (on a 4,000-scan THOR walk, 69 MB after scoring). Returns
    whether it could (not on another C library)."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        return False
    trim.argtypes = [ctypes.c_size_t]
    trim(0)
    return True
