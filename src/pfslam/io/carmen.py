"""CARMEN text logs (plain or gzip): FLASER, ROBOTLASER1, RAWLASER1..4, ODOM, PARAM.

Every record ends with ``ipc_timestamp ipc_hostname logger_timestamp``; the scan time is
the ``ipc_timestamp``. Unknown records are skipped and counted; malformed known records
are skipped, counted, and reported once per record type with their first line number.

Beam angles: ``ROBOTLASER1``/``RAWLASER`` carry start angle and resolution. ``FLASER``
carries only the beam count ``n``: its field of view (180 deg by default) starts at
-fov/2; ``n`` even (180, 360) means steps of fov/n (the last beam one step short of
+fov/2), ``n`` odd (181, 361) means steps of fov/(n-1) (both ends included).

A scan whose time stamp is earlier than the previous scan's is dropped and reported (with
the line number of the first) in the warnings; the real Intel log has four.

Readings at or beyond the sensor's maximum (FLASER: 80 m unless PARAM
``robot_front_laser_max`` or the user says otherwise; RAWLASER/ROBOTLASER1: the record's
``max_range``) are "no return".
"""

from __future__ import annotations

import gzip
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.geometry import relative, rz, txyz

Array = NDArray[np.float64]

NOMINAL_LASER_HEIGHT = 0.3  # m; planar lasers are level, so no beam is a floor hit
FLASER_MAX_RANGE = 80.0  # m; 81.83 / 81.91 in the classic logs mean "no return"
LASER_RECORDS = ("FLASER", "ROBOTLASER1", "RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")
KNOWN_RECORDS = LASER_RECORDS + ("ODOM", "PARAM", "NEFF", "SYNC", "TRUEPOS", "RLASER")


@dataclass
class CarmenLog:
    frames: list[Frame]
    reference: Array | None  # (N, 3) the pose each laser record carries (robot frame)
    counts: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    params: dict[str, str] = field(default_factory=dict)


def read_text_lines(path: Path) -> list[str]:
    """Lines of a plain or gzip text file (gzip detected by its magic bytes)."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file():
        raise InputError(path, "not a file")
    try:
        with open(path, "rb") as f:
            magic = f.read(2)
        if magic == b"\x1f\x8b":
            with gzip.open(path, "rb") as f:
                raw = f.read()
        else:
            raw = path.read_bytes()
    except (OSError, EOFError, gzip.BadGzipFile) as e:
        raise InputError(path, f"cannot read the file ({e})") from None
    if b"\x00" in raw[:4096]:
        raise InputError(path, "binary data, not a text log")
    return raw.decode("utf-8", errors="replace").splitlines()


def flaser_angles(n: int, fov_deg: float = 180.0) -> Array:
    fov = math.radians(fov_deg)
    step = fov / (n - 1) if n % 2 == 1 and n > 1 else fov / max(n, 1)
    return -fov / 2.0 + step * np.arange(n)


class _Bad(Exception):
    pass


def _floats(tokens: list[str]) -> list[float]:
    try:
        v = [float(t) for t in tokens]
    except ValueError:
        raise _Bad("non-numeric field") from None
    if not all(math.isfinite(x) for x in v):
        raise _Bad("NaN/inf field")
    return v


def _ranges(tokens: list[str]) -> Array:
    try:
        r = np.array(tokens, dtype=float)
    except ValueError:
        raise _Bad("non-numeric range") from None
    return r


def load_carmen(path: str | Path, *, fov_deg: float | None = None, max_range: float | None = None) -> CarmenLog:
    """Read a CARMEN log into Frames (odometry pose and laser mount per scan)."""
    p = Path(path)
    lines = read_text_lines(p)
    counts: dict[str, int] = {}
    first_bad: dict[str, tuple[int, str]] = {}
    params: dict[str, str] = {}
    frames: list[Frame] = []
    ref: list[Array] = []
    odom_t: list[float] = []
    odom_p: list[list[float]] = []
    angle_cache: dict[tuple[int, float, float], Array] = {}
    last_t = -math.inf
    last_line = 0
    first_back: dict[str, str] = {}

    def bad(kind: str, n: int, why: str) -> None:
        counts["skipped_bad"] = counts.get("skipped_bad", 0) + 1
        first_bad.setdefault(kind, (n, why))

    for n, line in enumerate(lines, 1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        kind = tok[0]
        if kind not in KNOWN_RECORDS:
            counts["unknown"] = counts.get("unknown", 0) + 1
            continue
        counts[kind] = counts.get(kind, 0) + 1
        try:
            if kind == "PARAM":
                if len(tok) >= 3:
                    params[tok[1]] = tok[2]
                continue
            if kind == "ODOM":
                if len(tok) < 10:
                    raise _Bad("too few fields")
                x, y, th = _floats(tok[1:4])
                t = _floats([tok[-3]])[0]
                odom_t.append(t)
                odom_p.append([x, y, th])
                continue
            if kind not in LASER_RECORDS:
                continue
            if len(tok) < 5:
                raise _Bad("too few fields")
            t = _floats([tok[-3]])[0]
            if kind == "FLASER":
                k = int(_floats([tok[1]])[0])
                if k <= 0 or len(tok) != 2 + k + 6 + 3:
                    raise _Bad(f"{len(tok)} fields for {k} ranges")
                r = _ranges(tok[2 : 2 + k])
                lx, ly, lth, ox, oy, oth = _floats(tok[2 + k : 2 + k + 6])
                fmax = max_range
                if fmax is None:
                    try:
                        fmax = float(params.get("robot_front_laser_max", FLASER_MAX_RANGE))
                    except ValueError:
                        fmax = FLASER_MAX_RANGE
                    fmax = min(fmax, FLASER_MAX_RANGE)
                key = (k, fov_deg or 180.0, 0.0)
                if key not in angle_cache:
                    angle_cache[key] = flaser_angles(k, fov_deg or 180.0)
                angles = angle_cache[key]
                odom = np.array([ox, oy, oth])
                laser = np.array([lx, ly, lth])
                mount_xyt = relative(odom, laser)
                if np.allclose(mount_xyt, 0.0, atol=1e-9):
                    try:
                        off = float(params.get("robot_frontlaser_offset", 0.0))
                    except ValueError:
                        off = 0.0
                    mount_xyt = np.array([off, 0.0, 0.0])
                pose_ref = odom
            else:
                # ROBOTLASER1 / RAWLASERx: type start fov res max acc mode n r.. n_rem rem..
                head = _floats(tok[2:9])
                start, fov, res, rmax = head[0], head[1], head[2], head[3]
                k = int(head[6])
                if k <= 0 or len(tok) < 9 + k + 1:
                    raise _Bad(f"{len(tok)} fields for {k} ranges")
                r = _ranges(tok[9 : 9 + k])
                nrem = int(_floats([tok[9 + k]])[0])
                rest = tok[10 + k + nrem :]
                fmax = max_range if max_range is not None else rmax
                key = (k, start, res)
                if key not in angle_cache:
                    angle_cache[key] = start + res * np.arange(k)
                angles = angle_cache[key]
                if kind == "ROBOTLASER1":
                    if len(rest) < 6 + 3:
                        raise _Bad("too few fields after the ranges")
                    lx, ly, lth, ox, oy, oth = _floats(rest[:6])
                    odom = np.array([ox, oy, oth])
                    mount_xyt = relative(odom, np.array([lx, ly, lth]))
                    pose_ref = odom
                else:
                    if not odom_t:
                        counts["before_first_odom"] = counts.get("before_first_odom", 0) + 1
                        continue
                    j = int(np.searchsorted(odom_t, t, side="right")) - 1
                    odom = np.array(odom_p[max(j, 0)])
                    mount_xyt = np.zeros(3)
                    pose_ref = odom
            if t < last_t:
                counts["time_backwards"] = counts.get("time_backwards", 0) + 1
                if "time" not in first_back:
                    first_back["time"] = f"line {n}: time goes backwards ({t:.6f} after {last_t:.6f} on line {last_line})"
                counts[kind] -= 1
                continue
            last_t, last_line = t, n
            r = np.where(np.isfinite(r) & (r < fmax - 0.01) & (r > 0), r, np.inf)
            mount = txyz(mount_xyt[0], mount_xyt[1], NOMINAL_LASER_HEIGHT) @ rz(mount_xyt[2])
            frames.append(Frame(t=t, ranges=r, angles=angles, odom=odom, mount=mount, min_range=0.0,
                                max_range=float(fmax)))
            ref.append(pose_ref)
        except _Bad as e:
            counts[kind] -= 1
            bad(kind, n, str(e))
        except (ValueError, IndexError, OverflowError):
            counts[kind] -= 1
            bad(kind, n, "malformed record")
    warnings = [f"{p}: skipped malformed {k} records (first on line {ln}: {why})" for k, (ln, why) in first_bad.items()]
    if first_back:
        warnings.append(f"{p}: dropped {counts['time_backwards']} scans whose time goes backwards "
                        f"(first: {first_back['time']})")
    if counts.get("unknown"):
        warnings.append(f"{p}: skipped {counts['unknown']} records of unknown types")
    if not frames:
        summary = ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) or "no records"
        raise InputError(p, f"no usable laser scans ({summary})")
    return CarmenLog(frames=frames, reference=np.array(ref), counts=counts, warnings=warnings, params=params)
