"""Odometry calibration from the scans themselves: scale factors and scan latency.

Wheel encoders are often documented with the wrong constant (a count per edge instead
of per period, a gearbox left out), and a laser's time stamp is often the moment the
scan reached the computer, a tenth of a second after it was taken. Both make the motion
model lie to the filter. :func:`calibrate` measures them without any ground truth:

1. **Scan-to-scan matching.** For scans ``i, j = i + gap`` the relative motion
   ``m_ij`` (pose of ``j`` in the frame of ``i``) is found by correlating ``j``'s hits
   with a smoothed wall map (``exp(-d²/2σ²)`` of the distance to ``i``'s hits), coarse to
   fine over a window around the odometry's own increment that is wide enough for scale
   errors up to 2× (``±(0.1 m + |u_xy|)``, ``±(5° + |u_θ|)``). Matches with little overlap
   or at the window edge are dropped.
2. **Fit.** For each candidate latency ``τ`` (the scan was taken ``τ`` seconds before its
   time stamp, so the odometry is read at ``t - τ``), the odometry increments
   ``u_ij(τ)`` are compared with the matched ones: the translation scale ``s_t`` is the
   least-squares slope of the matched forward motion on the odometry's, the rotation
   scale ``s_r`` that of the matched heading change on the odometry's, with outliers
   (more than 3 robust standard deviations) trimmed. The latency kept is the one whose
   fits leave the least unexplained variance ``(1 - R²_trans) + (1 - R²_rot)``.

:func:`apply_calibration` then reads the odometry at ``t - τ`` and scales it: wheel
travel as ``centre·s_t ± half-difference·s_r`` (so translation scales by ``s_t`` and
turning by ``s_r`` whatever the axle), odometry poses by re-chaining their increments
with x, y scaled by ``s_t`` and θ by ``s_r``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.config import CalibrationConfig, check_number
from pfslam.errors import PfslamError
from pfslam.frames import Frame, frame_column, frame_times, with_column
from pfslam.geometry import compose, relative, wrap_angle
from pfslam.kernels.scoring import correlation_kernel
from pfslam.maps.fields import gaussian_of_distance, wall_distance
from pfslam.motion import DiffDriveMotion
from pfslam.sensor import scan_to_points, subsample
from pfslam.types import Array


class CalibrationError(PfslamError):
    """The log cannot be calibrated (no odometry, too few usable scan pairs)."""


@dataclass
class Calibration:
    """What :func:`calibrate` found. ``scan_latency`` in s; scales multiply the odometry."""

    trans_scale: float = 1.0
    rot_scale: float = 1.0
    scan_latency: float = 0.0
    pairs_matched: int = 0
    pairs_used: int = 0
    trans_residual: float = float("nan")  # m, rms per step after the fit
    rot_residual_deg: float = float("nan")  # deg, rms per step after the fit
    rot_residual_deg_uncalibrated: float = float("nan")  # deg, with scale 1 and no latency
    source: str = "odometry"  # "wheels" or "odometry"

    def as_dict(self) -> dict[str, float | int | str]:
        return asdict(self)

    def explains_odometry(self) -> bool:
        """Whether the correction explains much of the odometry's difference from the scans
        (the heading residual per step cut by at least a fifth)."""
        return self.rot_residual_deg < 0.8 * self.rot_residual_deg_uncalibrated

    def plausible(self) -> bool:
        """Scales a real odometry can be off by (0.2-5) and a correction that explains much."""
        return 0.2 <= self.trans_scale <= 5.0 and 0.2 <= self.rot_scale <= 5.0 and self.explains_odometry()


# -- reading the odometry at shifted times -----------------------------------------


def _times(frames: Sequence[Frame]) -> Array:
    return frame_times(frames)


def _source(frames: Sequence[Frame]) -> str:
    if all(w is not None for w in frame_column(frames, "wheels")):
        return "wheels"
    if all(o is not None for o in frame_column(frames, "odom")):
        return "odometry"
    raise CalibrationError("the log has no odometry or wheel travel on every scan, nothing to calibrate")


def _shifted(frames: Sequence[Frame], latency: float, source: str) -> Array:
    """The odometry (N, 2) wheel travel or (N, 3) poses read at ``t - latency``, linearly
    interpolated between the log's samples (θ unwrapped), held at the ends."""
    t = _times(frames)
    if source == "wheels":
        vals = np.array([np.asarray(w, dtype=float) for w in frame_column(frames, "wheels")])
    else:
        vals = np.array([np.asarray(o, dtype=float) for o in frame_column(frames, "odom")])
        vals[:, 2] = np.unwrap(vals[:, 2])
    if latency == 0.0 or len(t) < 2:
        out = vals.copy()
    else:
        out = np.column_stack([np.interp(t - latency, t, vals[:, k]) for k in range(vals.shape[1])])
    if source != "wheels":
        out[:, 2] = wrap_angle(out[:, 2])
    return out


def _increments(frames: Sequence[Frame], latency: float, source: str, axle: float, pairs: NDArray[np.int64]) -> Array:
    """Odometry increment (x, y, θ) from scan i to scan j for each pair (i, j)."""
    vals = _shifted(frames, latency, source)
    a, b = vals[pairs[:, 0]], vals[pairs[:, 1]]
    if source == "wheels":
        d = b - a
        return DiffDriveMotion.arc(np.zeros((len(d), 3)), d[:, 0], d[:, 1], axle)
    return relative(a, b)


def shift_odometry(frames: Sequence[Frame], latency: float) -> Sequence[Frame]:
    """Frames whose odometry (wheel travel or poses) is read at ``t - latency``: for a
    laser whose time stamps are ``latency`` seconds late relative to the odometry."""
    return apply_calibration(frames, Calibration(scan_latency=latency))


def apply_calibration(frames: Sequence[Frame], cal: Calibration) -> Sequence[Frame]:
    """New frames with the latency and scales of ``cal`` applied to their odometry."""
    if not len(frames):
        return frames
    if cal.scan_latency == 0.0 and cal.trans_scale == 1.0 and cal.rot_scale == 1.0:
        return frames
    source = _source(frames)
    vals = _shifted(frames, cal.scan_latency, source)
    if source == "wheels":
        centre = vals.mean(axis=1) * cal.trans_scale
        half = 0.5 * (vals[:, 1] - vals[:, 0]) * cal.rot_scale
        new = np.column_stack([centre - half, centre + half])
    else:
        u = relative(vals[:-1], vals[1:])
        u[:, :2] *= cal.trans_scale
        u[:, 2] *= cal.rot_scale
        new = np.empty_like(vals)
        new[0] = vals[0]
        for k in range(len(u)):
            new[k + 1] = compose(new[k], u[k])
    return with_column(frames, "wheels" if source == "wheels" else "odom", new)


# -- scan matching ------------------------------------------------------------------


def _hits(frame: Frame, cfg: CalibrationConfig) -> Array:
    pts = scan_to_points(frame).hits
    if len(pts):
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) < cfg.max_reach]
    return np.ascontiguousarray(subsample(pts, cfg.max_points))


def _grid_poses(centre: Array, half_xy: float, step_xy: float, half_th: float, step_th: float) -> Array:
    nx = int(round(half_xy / step_xy))
    nt = int(round(half_th / step_th))
    d = np.arange(-nx, nx + 1) * step_xy
    th = np.arange(-nt, nt + 1) * step_th
    gx, gy, gt = np.meshgrid(d, d, th, indexing="ij")
    return np.ascontiguousarray(np.column_stack([gx.ravel(), gy.ravel(), gt.ravel()]) + centre)


def match_pair(ref: Array, query: Array, guess: Array, cfg: CalibrationConfig) -> tuple[Array, float, bool]:
    """Pose of the ``query`` scan in the frame of the ``ref`` scan (both (M, 2) robot-frame
    hits), searched around ``guess``. Returns (pose, overlap in 0..1, at window edge)."""
    res = cfg.resolution
    lo = ref.min(axis=0) - 1.0
    hi = ref.max(axis=0) + 1.0
    shape = (int(np.ceil((hi[1] - lo[1]) / res)) + 1, int(np.ceil((hi[0] - lo[0]) / res)) + 1)
    occ = np.zeros(shape, dtype=bool)
    cols = np.floor((ref[:, 0] - lo[0]) / res).astype(np.intp)
    rows = np.floor((ref[:, 1] - lo[1]) / res).astype(np.intp)
    occ[rows, cols] = True
    d = wall_distance(occ, res)
    coarse = gaussian_of_distance(d, cfg.sigma_coarse).astype(np.float32)
    fine = gaussian_of_distance(d, cfg.sigma_fine).astype(np.float32)
    inv = 1.0 / res
    ox, oy = float(lo[0]), float(lo[1])

    def best(poses: Array, field: NDArray[np.float32]) -> tuple[Array, float, int]:
        s = correlation_kernel(poses, query, field, ox, oy, inv, 1.0, 0.0)
        k = int(np.argmax(s))
        return poses[k], float(s[k]), k

    half_xy = min(0.1 + float(np.hypot(guess[0], guess[1])), 1.0)
    half_th = min(np.deg2rad(5.0) + abs(float(guess[2])), np.deg2rad(45.0))
    step_xy, step_th = 0.04, np.deg2rad(1.0)
    poses = _grid_poses(guess, half_xy, step_xy, half_th, step_th)
    p, _, _ = best(poses, coarse)
    off = p - guess
    edge = bool(
        abs(off[0]) > half_xy - step_xy / 2
        or abs(off[1]) > half_xy - step_xy / 2
        or abs(off[2]) > half_th - step_th / 2
    )
    for hxy, sxy, hth, sth in (
        (0.04, 0.01, np.deg2rad(1.5), np.deg2rad(0.25)),
        (0.01, 0.0025, np.deg2rad(0.3), np.deg2rad(0.05)),
    ):
        p, score, _ = best(_grid_poses(p, hxy, sxy, hth, sth), fine)
    return p, score / max(len(query), 1), edge


# -- the fit --------------------------------------------------------------------------


def _robust_slope(x: Array, y: Array) -> tuple[float, Array, NDArray[np.bool_]]:
    """Least-squares slope of y on x through the origin, trimming residuals beyond 3
    robust standard deviations (a few rounds). Returns (slope, residuals, kept)."""
    keep = np.ones(len(x), dtype=bool)
    s = 1.0
    for _ in range(5):
        xx, yy = x[keep], y[keep]
        den = float(np.dot(xx, xx))
        s = float(np.dot(xx, yy) / den) if den > 0 else 1.0
        r = y - s * x
        mad = float(np.median(np.abs(r[keep]))) * 1.4826
        new = np.abs(r) <= max(3.0 * mad, 1e-9)
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
    return s, y - s * x, keep


def _fit(meas: Array, odo: Array) -> tuple[float, float, float, float, float, NDArray[np.bool_]]:
    """Scales, the unexplained variance, rms residuals (m, rad) and the pairs kept."""
    fwd_m = np.sign(meas[:, 0]) * np.hypot(meas[:, 0], meas[:, 1])
    fwd_o = np.sign(odo[:, 0]) * np.hypot(odo[:, 0], odo[:, 1])
    st, rt, kt = _robust_slope(fwd_o, fwd_m)
    sr, rr, kr = _robust_slope(odo[:, 2], meas[:, 2])
    keep = kt & kr

    def unexplained(r: Array, y: Array) -> float:
        v = float(np.mean(y[keep] ** 2))
        return float(np.mean(r[keep] ** 2)) / v if v > 0 else 0.0

    cost = unexplained(rt, fwd_m) + unexplained(rr, meas[:, 2])
    return st, sr, cost, float(np.sqrt(np.mean(rt[keep] ** 2))), float(np.sqrt(np.mean(rr[keep] ** 2))), keep


def calibrate(
    frames: Sequence[Frame],
    config: CalibrationConfig | None = None,
    axle: float = 0.33,
    progress: Callable[[int, int], None] | None = None,
) -> Calibration:
    """Estimate the odometry's translation and rotation scale and the scan latency.

    ``axle`` (m, wheel logs only) must be finite and positive (ConfigError otherwise).
    """
    check_number("axle", axle, gt=0.0, what="a finite distance in metres")
    cfg = config or CalibrationConfig()
    n = len(frames)
    if n < 2:
        raise CalibrationError("need at least two scans to calibrate")
    source = _source(frames)
    t = _times(frames)
    if np.any(np.diff(t) < 0):
        raise CalibrationError("time stamps go backwards")
    gap = max(1, min(cfg.gap, n - 1))
    first = np.arange(n - gap)
    if len(first) > cfg.max_pairs:
        first = np.unique(np.linspace(0, n - 1 - gap, cfg.max_pairs).round().astype(np.int64))
    pairs = np.column_stack([first, first + gap]).astype(np.int64)
    guess = _increments(frames, 0.0, source, axle, pairs)
    meas = np.full((len(pairs), 3), np.nan)
    hits: dict[int, Array] = {}  # a scan is the query of one pair and the reference of another
    for k, (i, j) in enumerate(pairs):
        if progress is not None:
            progress(k, len(pairs))
        for f in (i, j):
            if f not in hits:
                hits[f] = _hits(frames[f], cfg)
        ref, query = hits[i], hits[j]
        if len(ref) < 30 or len(query) < 30:
            continue
        p, overlap, edge = match_pair(ref, query, guess[k], cfg)
        if overlap >= cfg.min_overlap and not edge:
            meas[k] = p
    if progress is not None:
        progress(len(pairs), len(pairs))
    ok = np.all(np.isfinite(meas), axis=1)
    moving = ok & ((np.hypot(guess[:, 0], guess[:, 1]) > 1e-3) | (np.abs(guess[:, 2]) > np.deg2rad(0.1)))
    if moving.sum() < cfg.min_pairs:
        raise CalibrationError(
            f"only {int(moving.sum())} scan pairs could be matched while the robot moved "
            f"(need {cfg.min_pairs}); the log is too short, too static or too featureless"
        )
    sel = pairs[moving]
    m = meas[moving]
    m[:, 2] = wrap_angle(m[:, 2])
    best: tuple[float, float, float, float, float, int] | None = None
    lat_best = 0.0
    for lat in np.arange(-cfg.max_latency, cfg.max_latency + cfg.latency_step / 2, cfg.latency_step):
        odo = _increments(frames, float(lat), source, axle, sel)
        st, sr, cost, rms_t, rms_r, keep = _fit(m, odo)
        if best is None or cost < best[2]:
            best = (st, sr, cost, rms_t, rms_r, int(keep.sum()))
            lat_best = float(lat)
    assert best is not None
    raw = guess[moving]  # the increments at latency 0, scale 1
    _, _, _, _, _, keep0 = _fit(m, raw)
    raw_rot = float(np.sqrt(np.mean(wrap_angle(m[keep0, 2] - raw[keep0, 2]) ** 2)))
    st, sr, _, rms_t, rms_r, used = best
    return Calibration(
        trans_scale=st,
        rot_scale=sr,
        scan_latency=round(lat_best, 6),
        pairs_matched=int(moving.sum()),
        pairs_used=used,
        trans_residual=rms_t,
        rot_residual_deg=float(np.rad2deg(rms_r)),
        rot_residual_deg_uncalibrated=float(np.rad2deg(raw_rot)),
        source=source,
    )
