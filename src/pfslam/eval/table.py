"""The figures runs are scored by, in one table: each metric's name (its key in run.json and a
sweep's table), the label it is shown under, its unit and the digits it is shown with. The
terminal's tables, a sweep's summary and its plots all read it."""

from __future__ import annotations

from dataclasses import dataclass

WITHIN_M = 0.3  # m: a localization is on the robot once its raw error stays within this


@dataclass(frozen=True)
class Metric:
    """One figure: ``name`` (the key), ``label``, ``unit`` ("" for a ratio or a count) and the
    ``digits`` after the point it is shown with."""

    name: str
    label: str
    unit: str = ""
    digits: int = 3

    @property
    def heading(self) -> str:
        """The label with its unit, as a column's heading: "ATE aligned (m)"."""
        return f"{self.label} ({self.unit})" if self.unit else self.label

    def show(self, value: float) -> str:
        """``value`` with this metric's digits."""
        return f"{value:.{self.digits}f}"


METRICS: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric("ate_raw", "ATE raw", "m", 3),
        Metric("ate_aligned", "ATE aligned", "m", 3),
        Metric("heading_rmse_deg", "heading RMSE", "deg", 2),
        Metric("rpe_trans", "RPE trans", "m", 4),
        Metric("relations_trans", "relations trans", "m", 3),
        Metric("relations_rot_deg", "relations rot", "deg", 2),
        Metric("map_agreement", "map agreement", "", 3),
        Metric("odometry_map_agreement", "odometry's map agreement", "", 3),
        Metric("within_after_s", f"within {WITHIN_M:g} m after", "s", 1),
        Metric("settle_s", "settle", "s", 1),
        Metric("lost_s", "lost", "s", 1),
        Metric("degraded_s", "degraded", "s", 1),
        Metric("quality_min", "lowest quality", "", 2),
        Metric("scans_per_s", "scans/s", "", 0),
        Metric("peak_rss_mb", "peak RSS", "MB", 0),
        Metric("backend_s", "back end", "s", 1),
        Metric("seconds", "filter loop", "s", 1),
    )
}


def heading(name: str) -> str:
    """The heading of metric ``name`` (the name itself for one the table does not hold)."""
    m = METRICS.get(name)
    return m.heading if m is not None else name
