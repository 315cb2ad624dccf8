"""Output folders: made before a long run (an unwritable one fails at once, saying why), and the
empty ones a failed run made, removed.

A leaf module, like :mod:`pfslam.io.common`: it imports nothing from :mod:`pfslam.io`."""

from __future__ import annotations

import errno
import os
from pathlib import Path

from pfslam.errors import InputError


def prepare_output_dir(out: Path) -> None:
    """Create the output folder before a long run, so an unwritable one fails at once; one
    that cannot be made is an InputError with the system's reason."""
    try:
        if out.exists() and not out.is_dir():
            raise InputError(out, "the output folder exists and is not a folder")
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(out, f"cannot create the output folder: {_mkdir_failure(out, e)}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(out, "the output folder is not writable")


def _mkdir_failure(out: Path, e: OSError) -> str:
    """Why ``out`` could not be made, said of the folder it was to be made in: the system's
    reason ("Permission denied", "Read-only file system"), or, where the system's words
    mislead (making a folder in /proc is "No such file or directory"), what happened."""
    base = Path(os.path.abspath(out)).parent
    while not os.path.lexists(base) and base != base.parent:
        base = base.parent
    if not base.is_dir():
        return f"{base} is not a folder"
    if e.errno == errno.ENOENT:  # the folder to make it in exists: its file system takes no new folders
        kind = _file_system(base)
        return f"{base} takes no new folders" + (f" (a {kind} file system)" if kind else f" ({e.strerror})")
    return f"{e.strerror or e} in {base}"


def _file_system(path: Path) -> str | None:
    """The type of the file system ``path`` is on (Linux: from /proc/self/mounts), or None."""
    try:
        text = Path("/proc/self/mounts").read_text()
    except OSError:
        return None
    where = os.path.realpath(path)
    best, kind = "", None
    for line in text.splitlines():
        parts = line.split()
        if len(parts) < 3:
            continue
        point = parts[1].replace("\\040", " ")
        inside = where == point or where.startswith(point.rstrip("/") + "/")
        if inside and len(point) >= len(best):
            best, kind = point, parts[2]
    return kind


def missing_folders(out: Path) -> list[Path]:
    """The folders that making ``out`` would create: ``out`` and its missing parents, deepest first."""
    made: list[Path] = []
    p = Path(os.path.abspath(out))
    while not os.path.lexists(p) and p != p.parent:
        made.append(p)
        p = p.parent
    return made


def remove_if_empty(folders: list[Path]) -> None:
    """Remove each of ``folders`` (deepest first) that exists and is empty; stop at the first
    that is not (``os.rmdir`` never removes a folder holding anything)."""
    for d in folders:
        if not os.path.lexists(d):
            continue
        try:
            os.rmdir(d)
        except OSError:
            return
