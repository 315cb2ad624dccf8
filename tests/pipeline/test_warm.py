"""The first run's compile (pfslam.pipeline.warm): said, and done in other processes, only
where the filter's kernels have nothing cached; never for the single-map filter."""

import subprocess
import sys

import pytest

import pfslam
from pfslam.config import SlamConfig
from pfslam.errors import InputError
from pfslam.pipeline import warm
from pfslam.pipeline.report import Quiet


def test_a_cache_filled_by_a_run_is_warm_and_an_empty_one_cold(tmp_path):
    from pfslam.filters.rbpf import load_kernels

    load_kernels()  # (the kernels compiled or loaded: their cache holds them)
    assert not warm.cold()
    code = "from pfslam.pipeline.warm import cold; print(cold())"
    env = {"NUMBA_CACHE_DIR": str(tmp_path), "PATH": ""}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"


def test_a_cold_cache_is_said_and_compiled_in_a_second_process(monkeypatch):
    monkeypatch.setattr(warm, "cold", lambda: True)
    rep = Quiet()
    w = warm.Warming(rep, SlamConfig())
    assert rep.lines == []  # (said only if the filter must wait: a log that cannot be read hears nothing of it)
    assert w.wait() == [0, 0]  # (one process per part of the kernels, not done yet when asked)
    assert rep.lines == [warm.COMPILING]
    single = Quiet()
    assert warm.Warming(single, SlamConfig(filter="single")).wait() == []
    assert single.lines == []


def test_a_config_the_filter_refuses_is_left_to_the_run_to_refuse(monkeypatch):
    """(The run refuses it where its config is made concrete, naming the file it came from.)"""
    from pfslam.config import with_values

    monkeypatch.setattr(warm, "cold", lambda: True)
    rep = Quiet()
    refused = with_values(SlamConfig(), {"sensor.temperature": 3.0})  # the single-map filter's, given to rbpf
    assert warm.Warming(rep, refused).wait() == []
    assert rep.lines == []


def test_a_log_that_cannot_be_read_starts_no_compile_and_says_only_its_error(monkeypatch, tmp_path):
    """On a cold cache too: the compile starts once the log is read, and is said only where the
    filter waits for it."""
    monkeypatch.setattr(warm, "cold", lambda: True)
    started = []
    monkeypatch.setattr(warm.subprocess, "Popen", lambda *a, **k: started.append(a))
    rep = Quiet()
    with pytest.raises(InputError):
        pfslam.slam(tmp_path / "missing.bag", tmp_path / "out", reporter=rep)
    assert started == []
    assert rep.lines == [] and rep.warnings == []
