"""The odometry's own errors, learnt where the scans pin the path, undone where they cannot.

A wheeled robot's odometry errs systematically: its distances read a few per cent long or short
(a wheel's diameter), its turns a few per cent too far or not far enough (the wheel base), and
its heading creeps by a fraction of a degree per metre (unequal wheels). Where scans match, the
filter's path shows them: each update's matched motion ``m`` against the odometry's ``u`` over
the same update. :class:`DriftFit` fits, by least squares over the matched updates (each
metre's evidence fading over :data:`HORIZON_M` of travel, so a change of floor or load is
followed),

* ``|u| = scale |m|`` and
* ``turn(u) = turn_scale turn(m) + bias |m|``,

and :meth:`DriftFit.undo` takes them out of an odometry increment. The filter uses it where no
scan can correct the odometry (a blind stretch: ``rbpf.blind_follow``), so that the path it
follows there drifts with the odometry's noise alone, not its bias. Each part is used only once
enough travel and turning back it (:data:`MIN_TRAVEL_M`, :data:`MIN_TURN_RAD`) and while it is
plausible (:data:`SCALE_RANGE`, :data:`MAX_BIAS`); otherwise that part is taken as exact.
"""

from __future__ import annotations

import numpy as np

from pfslam.types import Array, JSONObject

HORIZON_M = 500.0  # m of matched travel over which a metre's evidence fades to 1/e
MIN_TRAVEL_M = 30.0  # matched travel before the scale and the bias are used ...
MIN_TURN_RAD = 2 * np.pi  # ... and turning (rad, summed) before the turns' scale is
SCALE_RANGE = (0.8, 1.25)  # a fitted scale outside this is not the odometry's: not used
MAX_BIAS = np.deg2rad(2.0)  # rad per m: likewise for the heading's creep


class DriftFit:
    """The odometry's scale, turn scale and heading bias fitted from matched updates (see the
    module notes)."""

    def __init__(self) -> None:
        # decayed sums of d = |m|, dm = turn(m), du = turn(u), tu = |u| products
        self._s = np.zeros(8)

    def add(self, u: Array, m: Array) -> None:
        """One update's odometry increment ``u`` and matched motion ``m`` (x, y, theta, in the
        frame of the pose before)."""
        d = float(np.hypot(m[0], m[1]))
        tu = float(np.hypot(u[0], u[1]))
        tm, tuo = float(m[2]), float(u[2])
        self._s *= np.exp(-d / HORIZON_M)
        self._s += [d, tu * d, d * d, tm * tm, tm * d, tuo * tm, tuo * d, abs(tm)]

    @property
    def travel_m(self) -> float:
        return float(self._s[0])

    def fitted(self) -> tuple[float, float, float]:
        """(scale, turn scale, bias rad/m), each 1, 1, 0 where not backed or not plausible."""
        travel, tud, dd, mm, md, um, ud, turned = self._s
        scale, turn, bias = 1.0, 1.0, 0.0
        if travel < MIN_TRAVEL_M or dd <= 0:
            return scale, turn, bias
        s = tud / dd
        if SCALE_RANGE[0] <= s <= SCALE_RANGE[1]:
            scale = float(s)
        if turned >= MIN_TURN_RAD:
            det = mm * dd - md * md
            if det > 1e-12:
                r = (um * dd - md * ud) / det
                b = (mm * ud - md * um) / det
                if SCALE_RANGE[0] <= r <= SCALE_RANGE[1] and abs(b) <= MAX_BIAS:
                    return scale, float(r), float(b)
        b = (ud - md) / dd  # the turns taken as exact: the bias alone
        if abs(b) <= MAX_BIAS:
            bias = float(b)
        return scale, turn, bias

    def undo(self, u: Array) -> Array:
        """The odometry increment ``u`` with the fitted errors taken out."""
        scale, turn, bias = self.fitted()
        out = np.array(u, dtype=float)
        out[:2] /= scale
        out[2] = (out[2] - bias * float(np.hypot(out[0], out[1]))) / turn
        return out

    def as_dict(self) -> JSONObject:
        scale, turn, bias = self.fitted()
        return {
            "matched_travel_m": self.travel_m,
            "scale": scale,
            "turn_scale": turn,
            "bias_deg_per_m": float(np.rad2deg(bias)),
        }
