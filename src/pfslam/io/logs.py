"""Loader registry: pick the reader from the file, return format-independent frames."""

from __future__ import annotations

import gzip
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import Frame

FORMATS = ("thor", "carmen", "mines")


@dataclass
class LoadedLog:
    frames: list[Frame]
    format: str
    warnings: list[str] = field(default_factory=list)
    reference: NDArray[np.float64] | None = None  # (N, 3) poses the log carries, if corrected
    odometry: str = "log"  # where the frames' odometry came from


def detect_format(path: Path) -> str:
    """Name of the reader for ``path``, from its first bytes and extension."""
    name = path.name.lower()
    with open(path, "rb") as f:
        head = f.read(4096)
    if head.startswith(b"MATLAB") or head[:4] == b"\x89HDF" or name.endswith(".mat"):
        return "thor"
    if head[:2] == b"\x1f\x8b":
        try:
            with gzip.open(path, "rb") as g:
                head = g.read(4096)
        except (OSError, EOFError):
            raise InputError(path, "corrupt gzip file") from None
    text = head.decode("utf-8", errors="replace")
    words = {ln.split()[0] for ln in text.splitlines() if ln.split()}
    if words & {"FLASER", "ROBOTLASER1", "RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4", "ODOM", "PARAM"}:
        return "carmen"
    if name.endswith(".dat"):
        return "mines"
    raise InputError(path, "unknown log format (expected a THOR .mat, a CARMEN log or a Mines .dat file)")


def load_log(
    path: str | Path, joint: str | Path | None = None, odometry: str = "log", wheel_scale: float = 1.0
) -> LoadedLog:
    """Read any supported log into Frames.

    ``odometry``: "log" uses the log's own odometry; "synthetic[:SEED]" replaces it with
    drifting odometry derived from the poses a corrected log carries (see
    :mod:`pfslam.odometry`); the reference poses themselves never reach the filter.
    """
    from pfslam.odometry import parse_odometry_option, synthetic_odometry

    p = Path(path)
    if not p.exists():
        raise InputError(p, "file not found")
    if not p.is_file():
        raise InputError(p, "not a file")
    try:
        mode, seed = parse_odometry_option(odometry)
    except ValueError as e:
        raise InputError(p, str(e)) from None
    if not wheel_scale > 0:
        raise InputError(p, "--wheel-scale must be positive")
    fmt = detect_format(p)
    if joint is not None and fmt != "thor":
        raise InputError(joint, "a joint file only goes with a THOR lidar .mat file")
    if fmt == "thor":
        from pfslam.io.thor import load_thor

        log = load_thor(p, joint)
        out = LoadedLog(frames=log.frames, format=f"thor-{log.layout}", warnings=list(log.warnings))
    elif fmt == "carmen":
        from pfslam.io.carmen import load_carmen

        c = load_carmen(p)
        out = LoadedLog(frames=c.frames, format="carmen", warnings=list(c.warnings), reference=c.reference)
    else:
        from pfslam.io.mines import load_mines

        m = load_mines(p, wheel_scale=wheel_scale)
        out = LoadedLog(frames=m.frames, format="mines", warnings=list(m.warnings))
    if mode == "synthetic":
        if out.reference is None:
            raise InputError(p, "--odometry synthetic needs a log that carries reference poses (a CARMEN log)")
        odo = synthetic_odometry(out.reference, seed)
        for f, o in zip(out.frames, odo):
            f.odom = o
        out.odometry = f"synthetic:{seed}"
    return out
