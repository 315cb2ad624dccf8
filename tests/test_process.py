"""The process around a run (pfslam.process): the freed heap handed back to the system."""

import sys

import numpy as np
import pytest

from pfslam.process import hand_back_freed


def _resident_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim, /proc")
def test_the_holes_a_step_leaves_in_the_heap_are_handed_back():
    blocks = [np.ones(8000) for _ in range(1600)]  # 64 KB each: from the heap, not mapped apart
    del blocks[::2]  # every other freed: holes the heap cannot shrink past by itself
    before = _resident_mb()
    assert hand_back_freed()
    assert _resident_mb() < before - 20  # of the 50 MB freed
    assert sum(b.sum() for b in blocks) == 800 * 8000  # (the rest untouched)
