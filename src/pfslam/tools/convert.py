"""``pfslam convert``: any log pfslam reads, written as a ROS bag or a CARMEN log.

The log is loaded as every command loads it (:func:`pfslam.io.logs.load_log`, so
``--odometry synthetic`` on a corrected CARMEN log writes the synthetic odometry), then
written by :func:`pfslam.io.bagwrite.write_bag` (ROS 1 ``.bag``, ROS 2 sqlite3 folder, bare
``.mcap``) or :func:`pfslam.io.carmen.write_carmen`. A log with wheel travel instead of
odometry poses (Mines) is written with its dead-reckoned poses. The output is written
beside its place and moved there when complete: an existing output is only replaced with
``force`` (and never a folder that is not a ROS 2 bag).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from pfslam.errors import InputError
from pfslam.frames import frame_column

if TYPE_CHECKING:
    from pfslam.io.logs import BagOptions  # what options are: the ROS bag reader's (see convert)

TARGETS = ("ros1", "ros2", "mcap", "carmen")
DESCRIPTIONS = {"ros1": "ROS 1 bag", "ros2": "ROS 2 bag (sqlite3)", "mcap": "MCAP bag", "carmen": "CARMEN log"}


def target_format(out: Path, to: str | None = None) -> str:
    """The format to write: ``to`` if given, else from the name of ``out`` (``.bag`` ROS 1,
    ``.mcap`` MCAP, ``.log`` / ``.gz`` CARMEN, a name without a suffix or an existing
    folder a ROS 2 bag)."""
    if to is not None:
        key = to.strip().lower()
        if key not in TARGETS:
            raise InputError(out, f"--to must be one of {', '.join(TARGETS)}, not {to!r}")
        return key
    name = out.name.lower()
    if name.endswith(".bag"):
        return "ros1"
    if name.endswith(".mcap"):
        return "mcap"
    if name.endswith((".log", ".gz")):
        return "carmen"
    if out.is_dir() or not out.suffix:
        return "ros2"
    raise InputError(
        out, f"cannot tell the output format from the name ({out.suffix!r}): give --to {', '.join(TARGETS)}"
    )


@dataclass
class Converted:
    """What :func:`convert` wrote."""

    path: Path
    target: str
    scans: int
    source_format: str
    odometry: str
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what was done as asked (--level-head)

    @property
    def description(self) -> str:
        return DESCRIPTIONS[self.target]


def _check_output(src: Path, out: Path, force: bool) -> None:
    if not out.parent.is_dir():
        raise InputError(out, "the folder it would go in does not exist")
    if out.exists() or out.is_symlink():
        if out.resolve() == src.resolve():
            raise InputError(out, "is the input log itself")
        if not force:
            raise InputError(out, "exists already (--force replaces it)")
        if out.is_dir() and not (out / "metadata.yaml").is_file() and any(out.iterdir()):
            raise InputError(out, "is a folder that is not a ROS 2 bag: not replaced")


def _replace(tmp: Path, out: Path) -> None:
    """Put the finished output ``tmp`` in the place of ``out`` (removing what was there)."""
    if out.is_dir() and not out.is_symlink():
        shutil.rmtree(out)
    elif out.exists() or out.is_symlink():
        out.unlink()
    os.replace(tmp, out)


def convert(
    src: str | Path,
    out: str | Path,
    *,
    to: str | None = None,
    force: bool = False,
    joint: str | Path | None = None,
    odometry: str = "log",
    wheel_scale: float = 1.0,
    level_head: bool | None = None,
    max_scans: int | None = None,
    **options: str | None,
) -> Converted:
    """Read ``src`` (any log pfslam reads; ``options``: the ROS bag reader's topic and frame
    options; ``max_scans``: at most this many of its scans) and write it to ``out`` in the
    format :func:`target_format` gives.

    Raises:
        InputError: the input cannot be read, the output's format cannot be told, the output
            exists (without ``force``), or the frames cannot be written in the format.
    """
    from pfslam.io import bagwrite, carmen
    from pfslam.io.logs import load_log
    from pfslam.io.mines import dead_reckoning

    src, out = Path(src), Path(out)
    target = target_format(out, to)
    _check_output(src, out, force)
    log = load_log(
        src,
        joint,
        odometry=odometry,
        wheel_scale=wheel_scale,
        level_head=level_head,
        max_scans=max_scans,
        **cast("BagOptions", options),
    )
    frames = log.frames
    warnings = list(log.warnings)
    odom = frame_column(frames, "odom")
    if all(o is not None for o in odom):
        poses = np.array(odom, dtype=float).reshape(len(frames), 3)
    else:
        poses = dead_reckoning(list(frames))
        warnings.append(
            f"{src}: the log has wheel travel, not odometry poses: written as the poses dead reckoning gives"
        )
    with tempfile.TemporaryDirectory(prefix=".pfslam-convert-", dir=out.parent) as tmp:
        part = Path(tmp) / out.name
        if target == "carmen":
            warnings += carmen.write_carmen(part, frames, poses, source=src.name)
        else:
            warnings += bagwrite.write_bag(part, frames, poses, target)
        _replace(part, out)
    warnings = [w.replace(str(part), str(out)) for w in warnings]
    return Converted(out, target, len(frames), log.format, log.odometry, warnings, log.notes)
