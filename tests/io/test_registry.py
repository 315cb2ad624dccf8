"""The loader registry in pfslam.io.logs: loader modules stay independent, new formats plug in."""

import ast
import gzip
import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.io import common, folders, logs, matfile, matrecords, readings, rosmessages, times, transforms
from pfslam.io.common import LoadedLog
from pfslam.io.logs import REGISTRY, LogFormat, detect_format, load_log

IO = Path(logs.__file__).parent
LOADERS = sorted({entry.read.__module__ for entry in REGISTRY} | {entry.detect.__module__ for entry in REGISTRY})


def imported_names(module: str) -> set[str]:
    """Every module (and ``package.name`` of a ``from package import name``) a module's source
    imports, at any depth (function-level imports too), relative imports resolved."""
    path = Path(importlib.import_module(module).__file__)
    package = module.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    return out


def test_the_table_lists_the_formats_in_detection_order():
    assert [e.name for e in REGISTRY] == ["thor", "rosbag", "carmen", "mines"] == list(logs.FORMATS)
    assert LOADERS == ["pfslam.io.carmen", "pfslam.io.mines", "pfslam.io.rosbag", "pfslam.io.thor"]
    for entry in REGISTRY:
        assert entry.detect.__module__ == entry.read.__module__ == f"pfslam.io.{entry.name}"


@pytest.mark.parametrize("module", LOADERS)
def test_a_loader_module_imports_neither_the_registry_nor_another_loader(module):
    names = imported_names(module)
    forbidden = {"pfslam.io.logs"} | (set(LOADERS) - {module})
    assert not names & forbidden, f"{module} imports {sorted(names & forbidden)}"
    leaves = {  # what loaders may share
        "pfslam.io.common": common,
        "pfslam.io.matfile": matfile,
        "pfslam.io.matrecords": matrecords,
        "pfslam.io.transforms": transforms,
        "pfslam.io.rosmessages": rosmessages,
        "pfslam.io.times": times,
        "pfslam.io.readings": readings,
        "pfslam.io.folders": folders,
    }
    assert {n for n in names if n.startswith("pfslam.io")} <= set(leaves) | {
        f"{leaf}.{n}" for leaf, mod in leaves.items() for n in dir(mod)
    }


def test_common_is_a_leaf():
    names = imported_names("pfslam.io.common")
    assert not [n for n in names if n.startswith("pfslam.io")]


@pytest.mark.parametrize("module", LOADERS + ["pfslam.io.common"])
def test_importing_a_loader_alone_loads_no_other_io_module(module):
    code = (
        "import sys; import " + module + "; "
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('pfslam.io.'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    shared = {
        "pfslam.io.common",
        "pfslam.io.matfile",
        "pfslam.io.matrecords",
        "pfslam.io.rosmessages",
        "pfslam.io.transforms",
        "pfslam.io.times",
        "pfslam.io.readings",
    }
    assert set(out) <= {module} | shared


def test_nothing_in_pfslam_imports_the_shared_pieces_from_the_registry():
    shared = {"LoadedLog", "check_odometry", "ScanClock", "TIME_TOLERANCE"}
    src = IO.parent
    for path in sorted(src.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.module == "pfslam.io.logs":
                assert not {a.name for a in node.names} & shared, f"{path} imports {shared} from pfslam.io.logs"


# --- a new format plugs in with one line -----------------------------------------------------


def fake_frames(n: int = 3) -> list[Frame]:
    return [
        Frame(t=float(i), ranges=np.ones(4), angles=np.linspace(-1, 1, 4), odom=np.array([0.1 * i, 0.0, 0.0]))
        for i in range(n)
    ]


@pytest.fixture
def fake(monkeypatch):
    """A ``.fake`` format (files starting with ``FAKE``) registered after the built-in ones."""
    calls = []

    def detect(path: Path, head: bytes) -> bool:
        calls.append(("detect", path, head[:8]))
        return head.startswith(b"FAKE")

    def read(path: Path, *, joint=None, wheel_scale: float = 1.0) -> LoadedLog:
        calls.append(("read", path, joint, wheel_scale))
        return LoadedLog(frames=fake_frames(), format="fake-v1", warnings=[f"{path}: a fake log"])

    entry = LogFormat("fake", detect, read, "a FAKE log")
    monkeypatch.setattr(logs, "REGISTRY", [*REGISTRY, entry])
    return calls


def test_a_registered_reader_is_picked_up_by_load_log(tmp_path, fake):
    p = tmp_path / "x.fake"
    p.write_bytes(b"FAKE 1\n")
    assert detect_format(p) == "fake"
    log = load_log(str(p), wheel_scale=2.5)
    assert log.format == "fake-v1" and log.warnings == [f"{p}: a fake log"] and len(log.frames) == 3
    assert ("read", p, None, 2.5) in fake
    # its frames go through the same checks as the built-in formats'
    with pytest.raises(InputError, match="needs a log that carries reference poses"):
        load_log(p, odometry="synthetic")


def test_a_registered_text_format_sees_gzip_files_decompressed(tmp_path, fake):
    p = tmp_path / "x.gz"
    p.write_bytes(gzip.compress(b"FAKE 1\n"))
    assert detect_format(p) == "fake"
    assert ("detect", p, b"FAKE 1\n") in fake


def test_earlier_entries_win_and_the_unknown_format_error_names_every_entry(tmp_path, fake):
    carmen_too = tmp_path / "both.fake"
    carmen_too.write_text("FAKE\nFLASER 1 1.0 0 0 0 0 0 0 1 h 1\n")
    assert detect_format(carmen_too) == "carmen"  # CARMEN (a record starts a line) comes first
    q = tmp_path / "x.txt"
    q.write_text("hello\n")
    with pytest.raises(InputError) as e:
        detect_format(q)
    assert str(e.value) == (
        f"{q}: unknown log format (expected a THOR .mat, a ROS bag, a CARMEN log, a Mines .dat file or a FAKE log)"
    )


def test_the_unknown_format_error_is_unchanged_without_extra_entries(tmp_path):
    q = tmp_path / "x.txt"
    q.write_text("hello\n")
    with pytest.raises(InputError) as e:
        load_log(q)
    assert str(e.value) == (
        f"{q}: unknown log format (expected a THOR .mat, a ROS bag, a CARMEN log or a Mines .dat file)"
    )


def test_a_joint_file_is_rejected_by_the_readers_that_cannot_use_it(tmp_path):
    p = tmp_path / "a.log"
    p.write_text("FLASER 1 1.0 0 0 0 0 0 0 1 h 1\n")
    with pytest.raises(InputError) as e:
        load_log(p, joint=tmp_path / "j.mat")
    assert str(e.value) == f"{tmp_path / 'j.mat'}: a joint file only goes with a THOR lidar .mat file"


def test_detection_reads_only_detect_bytes(tmp_path, monkeypatch):
    p = tmp_path / "late.log"
    p.write_text("#" * 100 + "\nFLASER 1 1.0 0 0 0 0 0 0 1 h 1\n")
    assert detect_format(p) == "carmen"
    monkeypatch.setattr(common, "DETECT_BYTES", 50)
    with pytest.raises(InputError, match="unknown log format"):
        detect_format(p)
