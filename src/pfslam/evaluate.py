"""Trajectory metrics: ATE (raw and SE(2)-aligned) and RPE, as plain functions."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from pfslam.geometry import compose, relative, wrap_angle

Array = NDArray[np.float64]


def associate(t_est: Array, t_ref: Array, max_dt: float = 0.02) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Indices (i_est, i_ref) of pairs whose time stamps differ by at most ``max_dt`` (nearest match)."""
    t_est = np.asarray(t_est, float)
    t_ref = np.asarray(t_ref, float)
    order = np.argsort(t_ref)
    ts = t_ref[order]
    j = np.clip(np.searchsorted(ts, t_est), 1, len(ts) - 1) if len(ts) > 1 else np.zeros(len(t_est), int)
    if len(ts) > 1:
        left = ts[j - 1]
        right = ts[j]
        j = np.where(np.abs(t_est - left) <= np.abs(t_est - right), j - 1, j)
    ok = np.abs(ts[j] - t_est) <= max_dt
    return np.nonzero(ok)[0], order[j[ok]]


def align_se2(est: Array, ref: Array) -> Array:
    """The SE(2) pose (x, y, theta) that best maps ``est`` positions onto ``ref`` (least squares)."""
    a = est[:, :2]
    b = ref[:, :2]
    ma, mb = a.mean(0), b.mean(0)
    h = (a - ma).T @ (b - mb)
    th = np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    c, s = np.cos(th), np.sin(th)
    t = mb - np.array([[c, -s], [s, c]]) @ ma
    return np.array([t[0], t[1], th])


@dataclass
class TrajectoryErrors:
    """ATE and RPE between an estimate and a reference (metres and degrees)."""

    matched: int
    ate_rmse: float
    ate_rmse_aligned: float
    ate_max_aligned: float
    heading_rmse_deg: float
    rpe_trans_rmse: float
    rpe_rot_rmse_deg: float
    rpe_delta: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def trajectory_errors(
    t_est: Array, est: Array, t_ref: Array, ref: Array, max_dt: float = 0.02, rpe_delta: int = 10
) -> TrajectoryErrors:
    """ATE RMSE without and with SE(2) alignment, heading RMSE, and RPE over ``rpe_delta`` poses."""
    i, j = associate(t_est, t_ref, max_dt)
    if len(i) < 2:
        raise ValueError(f"only {len(i)} poses matched in time (max_dt={max_dt} s)")
    e, r = np.asarray(est, float)[i], np.asarray(ref, float)[j]
    raw = np.hypot(*(e[:, :2] - r[:, :2]).T)
    g = align_se2(e, r)
    ea = compose(g, e)
    al = np.hypot(*(ea[:, :2] - r[:, :2]).T)
    dh = wrap_angle(ea[:, 2] - r[:, 2])
    d = max(1, min(rpe_delta, len(i) - 1))
    de = relative(e[:-d], e[d:])
    dr = relative(r[:-d], r[d:])
    err = relative(dr, de)
    return TrajectoryErrors(
        matched=int(len(i)),
        ate_rmse=float(np.sqrt(np.mean(raw**2))),
        ate_rmse_aligned=float(np.sqrt(np.mean(al**2))),
        ate_max_aligned=float(al.max()),
        heading_rmse_deg=float(np.rad2deg(np.sqrt(np.mean(dh**2)))),
        rpe_trans_rmse=float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1)))),
        rpe_rot_rmse_deg=float(np.rad2deg(np.sqrt(np.mean(err[:, 2] ** 2)))),
        rpe_delta=d,
    )
