"""Trajectory metrics: ATE (raw and SE(2)-aligned) and RPE, as plain functions."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.config import check_int, check_number
from pfslam.geometry import compose, relative, transform_points, wrap_angle
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.frames import Frame
    from pfslam.maps.grid import OccupancyGrid
    from pfslam.sensor import ScanPoints


def associate(t_est: Array, t_ref: Array, max_dt: float = 0.02) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Indices (i_est, i_ref) of pairs whose time stamps differ by at most ``max_dt`` (nearest match)."""
    check_number("max_dt", max_dt, gt=0.0, what="a finite number of seconds")
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


@dataclass
class PoseErrors:
    """An estimate matched in time to a reference, pose by pose (what the error plots show)."""

    t: Array  # times of the matched estimated poses
    index: NDArray[np.intp]  # which estimated poses matched
    estimate: Array  # (M, 3) matched estimated poses
    aligned: Array  # (M, 3) the same after the best SE(2) alignment onto the reference
    reference: Array  # (M, 3) matched reference poses
    aligned_error: Array  # (M,) position error after alignment (m)


def pose_errors(t_est: Array, est: Array, t_ref: Array, ref: Array, max_dt: float = 0.02) -> PoseErrors:
    """Match ``est`` to ``ref`` in time (within ``max_dt``), align it (SE(2)) and give each
    matched pose's position error; ValueError if fewer than two poses match."""
    i, j = associate(t_est, t_ref, max_dt)
    if len(i) < 2:
        raise ValueError(f"only {len(i)} poses matched in time (max_dt={max_dt} s)")
    e, r = np.asarray(est, float)[i], np.asarray(ref, float)[j]
    ea = compose(align_se2(e, r), e)
    return PoseErrors(np.asarray(t_est, float)[i], i, e, ea, r, np.hypot(*(ea[:, :2] - r[:, :2]).T))


def trajectory_errors(
    t_est: Array, est: Array, t_ref: Array, ref: Array, max_dt: float = 0.02, rpe_delta: int = 10
) -> TrajectoryErrors:
    """ATE RMSE without and with SE(2) alignment, heading RMSE, and RPE over ``rpe_delta`` poses
    (an integer >= 1, lowered to the number of matched poses - 1 for short trajectories)."""
    check_int("rpe_delta", rpe_delta, 1)
    pe = pose_errors(t_est, est, t_ref, ref, max_dt)
    e, r, al = pe.estimate, pe.reference, pe.aligned_error
    i = pe.index
    raw = np.hypot(*(e[:, :2] - r[:, :2]).T)
    dh = wrap_angle(pe.aligned[:, 2] - r[:, 2])
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


@dataclass
class RelationErrors:
    """The relations metric of the SLAM benchmark (Kümmerle et al. 2009).

    ``skipped`` relations were not evaluated: ``unmatched`` have an end with no estimated
    pose within ``max_dt``, ``same_pose`` have both ends on the same estimated pose (two raw
    scans a few milliseconds apart that a thinned log holds as one scan: the estimate
    can only say "no motion" there, a false zero, not an error of the estimate)."""

    matched: int
    skipped: int
    trans_mean: float  # m
    trans_std: float
    rot_mean_deg: float  # absolute rotational error
    rot_std_deg: float
    unmatched: int = 0
    same_pose: int = 0

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def read_relations(path: str | Path) -> Array:
    """Rows ``t1 t2 x y yaw`` from a benchmark relations file (``t1 t2 x y z roll pitch yaw``)."""
    from pfslam.errors import InputError

    p = Path(path)
    if not p.is_file():
        raise InputError(p, "relations file not found")
    rows = []
    for n, line in enumerate(p.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
        s = line.split()
        if not s or s[0].startswith("#"):
            continue
        try:
            v = [float(x) for x in s]
        except ValueError:
            raise InputError(p, f"line {n}: not numeric") from None
        if len(v) != 8 or not np.isfinite(v).all():
            raise InputError(p, f"line {n}: expected 8 finite numbers 't1 t2 x y z roll pitch yaw', got {len(v)}")
        rows.append((v[0], v[1], v[2], v[3], v[7]))
    if not rows:
        raise InputError(p, "no relations")
    return np.array(rows)


def relation_errors(
    t_est: Array, est: Array, relations: Array, time_offset: float = 0.0, max_dt: float = 0.02
) -> RelationErrors:
    """For every relation whose two time stamps (after subtracting ``time_offset``) match two
    different estimated poses within ``max_dt`` each, the error between the estimated relative
    motion and the true one: mean and std of its translation (m) and of the absolute rotation
    (deg). Relations with an end matching no pose, or both ends on the same pose, are skipped
    and counted (see :class:`RelationErrors`)."""
    check_number("time_offset", time_offset, what="a finite number of seconds")
    t_est = np.asarray(t_est, float)
    est = np.asarray(est, float)
    rel = np.asarray(relations, float)
    i1, k1 = associate(rel[:, 0] - time_offset, t_est, max_dt)
    i2, k2 = associate(rel[:, 1] - time_offset, t_est, max_dt)
    first = dict(zip(i1.tolist(), k1.tolist()))
    second = dict(zip(i2.tolist(), k2.tolist()))
    ends = sorted(set(first) & set(second))
    both = [i for i in ends if first[i] != second[i]]
    unmatched, same = len(rel) - len(ends), len(ends) - len(both)
    if not both:
        nan = float("nan")
        return RelationErrors(0, len(rel), nan, nan, nan, nan, unmatched=unmatched, same_pose=same)
    a = est[[first[i] for i in both]]
    b = est[[second[i] for i in both]]
    d_est = relative(a, b)
    d_true = rel[both][:, 2:5]
    err = relative(d_true, d_est)
    tr = np.hypot(err[:, 0], err[:, 1])
    rot = np.rad2deg(np.abs(wrap_angle(err[:, 2])))
    return RelationErrors(
        matched=len(both),
        skipped=len(rel) - len(both),
        trans_mean=float(tr.mean()),
        trans_std=float(tr.std()),
        rot_mean_deg=float(rot.mean()),
        rot_std_deg=float(rot.std()),
        unmatched=unmatched,
        same_pose=same,
    )


def _thinning(n: int, max_scans: int) -> int:
    """The step that thins ``n`` scans to at most ``max_scans``."""
    return max(1, -(-n // max_scans))


def agreement_points(frames: Sequence[Frame], max_scans: int = 2000) -> list[ScanPoints]:
    """The scan points :func:`map_agreement` reads from ``frames`` (thinned as it thins them)."""
    from pfslam.sensor import scan_to_points

    return [scan_to_points(f) for f in frames[:: _thinning(len(frames), max_scans)]]


def map_agreement(
    frames: Sequence[Frame],
    poses: Array,
    splits: Sequence[float] = (0.25, 0.5, 0.75),
    tol: float = 0.1,
    resolution: float = 0.05,
    max_scans: int = 2000,
    points: Sequence[ScanPoints] | None = None,
) -> float:
    """A consistency figure that needs no ground truth (see :func:`agreement_fractions`): the
    mean of each split's scans' fractions, averaged over the splits; NaN if no later scan
    re-observes mapped space."""
    return agreement_of(agreement_fractions(frames, poses, splits, tol, resolution, max_scans, points))


def agreement_of(fractions: Sequence[Array | None]) -> float:
    """The map agreement of :func:`agreement_fractions`' per-split fractions."""
    scores = [float(np.nanmean(f)) for f in fractions if f is not None and np.isfinite(f).any()]
    return float(np.mean(scores)) if scores else float("nan")


def agreement_change(a: Sequence[Array | None], b: Sequence[Array | None], blocks: int = 10) -> tuple[float, float]:
    """How much trajectory ``b``'s map agreement exceeds ``a``'s (their
    :func:`agreement_fractions` over the same frames), and the standard error of that change:
    per split, the scans both score are cut into ``blocks`` runs of consecutive scans (nearby
    scans err together), and the spread of the runs' mean differences gives the error (batch
    means). (NaN, NaN) if they have no split in common."""
    diffs: list[float] = []
    var = 0.0
    for fa, fb in zip(a, b):
        if fa is None or fb is None:
            continue
        both = np.isfinite(fa) & np.isfinite(fb)
        if not both.any():
            continue
        diffs.append(float(np.nanmean(fb)) - float(np.nanmean(fa)))
        d = (fb - fa)[both]
        k = min(blocks, len(d))
        if k > 1:
            means = np.array([c.mean() for c in np.array_split(d, k)])
            var += float(means.var(ddof=1)) / k
    if not diffs:
        return float("nan"), float("nan")
    return float(np.mean(diffs)), float(np.sqrt(var)) / len(diffs)


def _scans_box(points: Sequence[ScanPoints], poses: Array) -> tuple[float, float, float, float] | None:
    """The box (x min, y min, x max, y max) of the scans' sensors and points at ``poses``: what a
    map drawn from them grows to hold."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for sp, pose in zip(points, poses):
        pts = (
            np.concatenate([sp.hits, sp.floor, sp.sensor_xy[None]])
            if len(sp.floor)
            else np.vstack([sp.hits, sp.sensor_xy[None]])
        )
        w = transform_points(pose, pts)
        lo, hi = np.minimum(lo, w.min(axis=0)), np.maximum(hi, w.max(axis=0))
    return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])) if np.isfinite(lo).all() else None


def _snapshot(
    logodds: NDArray[np.float32], occ: NDArray[np.bool_], disk: NDArray[np.bool_]
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], int, int]:
    """The map at a split, cropped to its observed cells: the cells within reach of an occupied
    one (``disk``), the observed ones, and the crop's first row and column in the map."""
    from scipy.ndimage import binary_dilation

    seen = logodds != 0
    rows, cols = np.nonzero(seen.any(axis=1))[0], np.nonzero(seen.any(axis=0))[0]
    r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    return binary_dilation(occ[r0:r1, c0:c1], disk), seen[r0:r1, c0:c1].copy(), r0, c0


def agreement_fractions(
    frames: Sequence[Frame],
    poses: Array,
    splits: Sequence[float] = (0.25, 0.5, 0.75),
    tol: float = 0.1,
    resolution: float = 0.05,
    max_scans: int = 2000,
    points: Sequence[ScanPoints] | None = None,
) -> list[Array | None]:
    """A consistency figure that needs no ground truth: how well later scans, placed at
    their estimated poses, land on the walls mapped by the earlier ones.

    For each ``split`` a map is built from the first ``split`` of the scans (one map, grown
    from split to split); for each later
    scan, its hits that fall in cells that map has observed (free or occupied) are checked
    against it, and the fraction within ``tol`` metres of an occupied cell is taken. The
    figure is the mean over those scans, averaged over the splits (one split alone depends
    a lot on where the robot happens to be at that moment). A trajectory that drifts puts
    later walls beside the earlier ones and scores low; 1.0 means every re-observed wall
    lands where it was mapped. Long logs are thinned evenly to at most ``max_scans`` scans.
    ``points``: the thinned frames' scan points (:func:`agreement_points`), when several
    trajectories of one log are scored. Returns, per split, the fraction of each later scan
    (NaN where the scan re-observes no mapped cell), or None where the map had no wall yet.
    """
    from dataclasses import replace

    from pfslam.config import MapConfig
    from pfslam.kernels.raycast import agreement_kernel
    from pfslam.maps.grid import grid_from_config

    n = min(len(frames), len(poses))
    step = _thinning(n, max_scans)
    if points is None:
        points = agreement_points(frames[:n], max_scans)
    poses = np.asarray(poses, dtype=float)[:n:step]
    n = len(poses)
    if len(points) != n:
        raise ValueError(f"{len(points)} scans of points for {n} thinned poses")
    mc = MapConfig()
    g = grid_from_config(replace(mc, resolution=resolution), centred=False)
    # "Within tol of an occupied cell" as the distance transform measures it (cell centre to
    # cell centre), checked only around the hits: the cells at these offsets.
    reach = int(np.ceil(tol / resolution))
    near = [
        (di, dj)
        for di in range(-reach, reach + 1)
        for dj in range(-reach, reach + 1)
        if np.sqrt(float(di * di + dj * dj)) * resolution < tol
    ]
    disk = np.zeros((2 * reach + 1, 2 * reach + 1), dtype=bool)
    for di, dj in near:
        disk[di + reach, dj + reach] = True
    marks = sorted(int(n * split) for split in splits if 1 <= int(n * split) < n)
    last = marks[-1] if marks else 0
    # The map made as large as the scans it takes will need, once: growing it scan by scan
    # (half again on a side each time) left it up to twice too wide and held the old and the
    # new side by side (on a 250 m campus, 1 GB). Its cells are where growing puts them.
    box = _scans_box(points[:last], poses[:last])
    if box is not None:
        g.ensure_contains(*box)
    # One pass: the map as it was at each split is kept (its occupied and observed cells,
    # cropped to the observed ones) and every later scan is checked against each kept map.
    kept: list[tuple[NDArray[np.bool_], NDArray[np.bool_], int, int] | None] = []
    fractions: list[Array | None] = []
    drawn = 0  # the scans before this are in the map (drawn a batch at a time, at each split)
    for i, (sp, pose) in enumerate(zip(points, poses)):
        if i in marks:
            _draw(g, points[drawn:i], poses[drawn:i])
            drawn = i
        for _ in range(marks.count(i)):
            occ = g.logodds > mc.l_occ / 3
            # the cells within tol of an occupied one, once per split (a lookup per hit after;
            # only those of observed cells are read, and every occupied cell is observed)
            kept.append(_snapshot(g.logodds, occ, disk) if occ.any() else None)
            fractions.append(np.full(n - i, np.nan) if occ.any() else None)
        ox, oy = float(g.origin[0]), float(g.origin[1])
        for snap, out, mark in zip(kept, fractions, marks):
            if snap is not None and out is not None:
                near_wall, seen, r0, c0 = snap
                known, on_wall = agreement_kernel(pose, sp.hits, near_wall, seen, ox, oy, resolution, r0, c0)
                if known:
                    out[i - mark] = on_wall / known
    return fractions


DRAW_BATCH = 200  # scans drawn in one kernel call (their points side by side: a few MB)


def _draw(grid: OccupancyGrid, points: Sequence[ScanPoints], poses: Array) -> None:
    """Ray-update ``grid`` (already large enough) with the scans ``points`` seen from ``poses``,
    in order, hits occupied and floor hits free (as :func:`~pfslam.maps.grid.integrate_scan`
    does one scan), a batch of scans per kernel call."""
    from pfslam.maps.grid import scan_beams

    for b in range(0, len(points), DRAW_BATCH):
        sensors, ends, hits = zip(
            *(scan_beams(pose, sp) for sp, pose in zip(points[b : b + DRAW_BATCH], poses[b : b + DRAW_BATCH]))
        )
        starts = np.concatenate([[0], np.cumsum([len(e) for e in ends])]).astype(np.int64)
        grid.update_scans(
            np.array(sensors).reshape(-1, 2), np.concatenate(ends).reshape(-1, 2), np.concatenate(hits), starts
        )
