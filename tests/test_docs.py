"""Every command in README.md and docs/*.md runs as written, from the repository root.

A page's ```bash blocks run in order, one shell each (a line ending in a backslash goes on
to the next), in a scratch folder that holds the
repository's files (links) with the recordings at ``../shared/data`` beside it, as a user's
clone has them. ``PFSLAM_MAX_SCANS`` shortens every log (the runs say so in a warning), so a
page costs seconds; the text is never edited. ```sh blocks (installing, starting servers)
are not run: the CI's own set-up runs the README's two. The ```python blocks (docs/api.md)
are run, and their outputs checked, by tests/test_api.py.

Each command must exit 0, and the files a page names as written by a command must be there.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from datafiles import DATA

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
SCANS = "120"  # per log: enough for every command to do its work, in about a second


def blocks(page: Path) -> list[tuple[str, str]]:
    """The page's fenced blocks: (language, text)."""
    return [(m.group(1), m.group(2)) for m in FENCE.finditer(page.read_text())]


def test_the_pages_hold_commands_and_only_known_block_kinds():
    """A test that extracted nothing would pass by itself: the pages hold runnable blocks,
    and no block is of a kind this test would silently skip."""
    kinds = {lang for page in PAGES for lang, _ in blocks(page)}
    assert kinds <= {"bash", "python", "sh", "yaml", "text", ""}, kinds
    runnable = [page.name for page in PAGES if any(lang == "bash" for lang, _ in blocks(page))]
    assert "README.md" in runnable and len(runnable) >= 6, runnable


def _sandbox(tmp: Path) -> Path:
    """A folder that looks like the repository root, with ../shared/data beside it."""
    root = tmp / "pfslam"
    root.mkdir()
    for entry in ROOT.iterdir():
        if entry.name not in (".git", ".venv", "out", "demo_out"):
            (root / entry.name).symlink_to(entry)
    (tmp / "shared").mkdir()
    (tmp / "shared" / "data").symlink_to(DATA)
    return root


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_command_of_the_page_runs_as_written(page: Path, tmp_path: Path):
    todo = [(lang, text) for lang, text in blocks(page) if lang == "bash"]
    if not todo:
        pytest.skip(f"{page.name} has no command")
    if not DATA.exists():
        pytest.skip(f"real recordings {DATA} not found (set PFSLAM_DATA)")
    root = _sandbox(tmp_path)
    bindir = str(Path(sys.executable).parent)
    env = {**os.environ, "PFSLAM_MAX_SCANS": SCANS, "PATH": bindir + os.pathsep + os.environ.get("PATH", "")}
    env.pop("PFSLAM_DATA", None)  # the pages name ../shared/data, as a clone has it
    for lang, text in todo:
        cmd = ["bash", "-e", "-o", "pipefail", "-c", text]
        proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"{page.name}: a {lang} block failed:\n{text}\n--- stderr:\n{proc.stderr[-3000:]}"
    # what the page's commands say they write (-o FOLDER) is there, with its results
    for _lang, text in todo:
        for out in re.findall(r"(?:-o|--out) (\S+)", text):
            folder = root / out
            assert folder.is_dir() and any(folder.iterdir()), f"{page.name}: {out} was not written"
