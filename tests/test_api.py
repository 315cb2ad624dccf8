"""The Python API: the names ``pfslam`` exports resolve to what they document, and the
API page's scripts (docs/api.md) run verbatim and do what they say."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pfslam

API_PAGE = Path(__file__).resolve().parent.parent / "docs" / "api.md"


def test_every_exported_name_resolves_and_is_documented():
    for name in pfslam.__all__:
        obj = getattr(pfslam, name)
        if name != "__version__":
            assert obj.__doc__ and obj.__doc__.strip(), name
    assert pfslam.Slam is pfslam.SingleMapSlam
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        pfslam.Nope  # noqa: B018
    assert set(pfslam.__all__) <= set(dir(pfslam))


def test_importing_pfslam_imports_no_filter_or_numba():
    code = "import sys, pfslam; print(any(m.startswith(('numba', 'pfslam.filters', 'scipy')) for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


@pytest.mark.slow
def test_the_api_page_scripts_run_verbatim(tmp_path):
    scripts = re.findall(r"```python\n(.*?)```", API_PAGE.read_text(), re.S)
    assert len(scripts) == 2  # a whole run as pfslam slam makes it; stepping a filter
    for script in scripts:
        r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        m = re.search(r"(\d+) scans, ATE ([\d.]+) m \(aligned ([\d.]+) m\)", r.stdout)
        assert m, r.stdout
        assert int(m.group(1)) == 800  # 20 s at 40 Hz
        assert float(m.group(3)) < 0.1  # the filter tracks the short walk
    out = tmp_path / "api_demo"
    for folder in (out, out / "out"):  # the stepped filter's files, and pfslam.slam's
        assert (folder / "map.pgm").stat().st_size > 1000 and "resolution: 0.05" in (folder / "map.yaml").read_text()
        tum = np.loadtxt(folder / "trajectory.tum")
        assert tum.shape == (800, 8) and (np.diff(tum[:, 0]) > 0).all()
    # The two ways are the same filter with the same settings: the same trajectory.
    np.testing.assert_array_equal(np.loadtxt(out / "trajectory.tum"), np.loadtxt(out / "out" / "trajectory.tum"))
