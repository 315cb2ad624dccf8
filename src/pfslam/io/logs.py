"""Loader registry: pick the reader from the file, return format-independent frames."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from pfslam.errors import InputError
from pfslam.frames import Frame


@dataclass
class LoadedLog:
    frames: list[Frame]
    format: str
    warnings: list[str] = field(default_factory=list)


def detect_format(path: Path) -> str:
    """Name of the reader for ``path``, from its extension and first bytes."""
    name = path.name.lower()
    with open(path, "rb") as f:
        head = f.read(128)
    if name.endswith(".mat") or head.startswith(b"MATLAB"):
        return "thor"
    raise InputError(path, "unknown log format (expected a THOR .mat file)")


def load_log(path: str | Path, joint: str | Path | None = None) -> LoadedLog:
    """Read any supported log into Frames."""
    p = Path(path)
    if not p.exists():
        raise InputError(p, "file not found")
    if not p.is_file():
        raise InputError(p, "not a file")
    fmt = detect_format(p)
    if fmt == "thor":
        from pfslam.io.thor import load_thor

        log = load_thor(p, joint)
        return LoadedLog(frames=log.frames, format=f"thor-{log.layout}", warnings=list(log.warnings))
    raise InputError(p, f"no reader for format {fmt}")  # pragma: no cover
