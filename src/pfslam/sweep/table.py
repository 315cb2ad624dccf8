"""A sweep's table: rows into ``results.csv``/``.parquet``, statistics per setting combination
and ``summary.png`` (see :mod:`pfslam.sweep`). Nothing here prints."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Sequence, cast

import numpy as np

if TYPE_CHECKING:
    import pandas as pd
from pfslam.eval.table import heading
from pfslam.sweep.columns import (
    COUNT_METRICS,
    HEAD_COLUMNS,
    STATUS_COLUMNS,
    TAIL_COLUMNS,
    metric_columns,
    summary_metrics,
)
from pfslam.sweep.spec import settings_text
from pfslam.types import JSON, JSONObject

# -- the table, the summary, the picture ---------------------------------------------------


def build_table(rows: Sequence[JSONObject], setting_keys: Sequence[str], run: str = "slam") -> pd.DataFrame:
    """One row per run: log, seed, one column per setting, status, exit code, message, the
    metrics (of ``run``: :func:`~pfslam.sweep.columns.metric_columns`), run folder (relative to
    the sweep's folder)."""
    import pandas as pd

    metrics = metric_columns(run)
    columns = [*HEAD_COLUMNS, *setting_keys, *STATUS_COLUMNS, *metrics, *TAIL_COLUMNS]
    records = []
    for row in rows:
        rec = {c: row.get(c) for c in columns}
        settings = cast("Mapping[str, JSON]", row.get("settings") or {})  # a row's settings are a mapping (runner._row)
        for k in setting_keys:
            rec[k] = settings.get(k)
        records.append(rec)
    df = pd.DataFrame.from_records(records, columns=columns)
    for m in metrics:
        df[m] = pd.to_numeric(df[m], errors="coerce").astype("Int64" if m in COUNT_METRICS else "float64")
    df["seed"] = df["seed"].astype("int64")
    df["exit_code"] = df["exit_code"].astype("Int64")
    for c in ("log", "status", "message", "run_dir"):
        df[c] = df[c].astype("string")
    df["message"] = df["message"].fillna("")
    for k in setting_keys:  # a setting column holds values of one type (the config field's)
        values = [v for v in df[k] if v is not None]
        if values and all(isinstance(v, bool) for v in values):
            df[k] = df[k].astype("boolean")
        elif values and all(isinstance(v, str) for v in values):
            df[k] = df[k].astype("string")
    return df


def write_table(df: pd.DataFrame, out_dir: str | Path) -> tuple[Path, Path]:
    """``results.csv`` and ``results.parquet`` in ``out_dir`` (written atomically)."""
    out = Path(out_dir)
    csv, parquet = out / "results.csv", out / "results.parquet"
    for path, write in (
        (csv, lambda p: df.to_csv(p, index=False)),
        (parquet, lambda p: df.to_parquet(p, index=False, engine="pyarrow")),
    ):
        tmp = path.with_name(f".{path.name}.tmp")
        write(tmp)
        os.replace(tmp, path)
    return csv, parquet


def _summarised(df: pd.DataFrame) -> list[str]:
    """The metrics of :func:`~pfslam.sweep.columns.summary_metrics` the table has (a localize
    sweep's settle time too)."""
    return [m for m in summary_metrics("localize") if m in df.columns]


def summarize(df: pd.DataFrame, setting_keys: Sequence[str]) -> pd.DataFrame:
    """Per log × setting combination (in the table's order): runs, ok and failed counts, and
    the median, min and max over the ok runs of each summary metric the table has (see
    :func:`~pfslam.sweep.columns.summary_metrics`; columns ``<metric>_median``, ``_min``,
    ``_max``; NaN without ok runs). A localize sweep's settle time is over the ok runs that
    settled; ``unsettled`` counts those that did not, ``off_at_end`` those that ended more
    than 0.3 m off the ground truth."""
    import pandas as pd

    keys = ["log", *setting_keys]
    records = []
    for group, part in df.groupby(keys, sort=False, dropna=False):
        group = group if isinstance(group, tuple) else (group,)
        ok = part[part["status"] == "ok"]
        rec: dict[str, object] = dict(zip(keys, group))
        rec.update(runs=len(part), ok=len(ok), failed=len(part) - len(ok))
        if "settle_s" in df.columns:
            rec["unsettled"] = int(ok["settle_s"].isna().sum())
        if "within_after_s" in df.columns:  # scored against a truth, and ended off the robot
            rec["off_at_end"] = int((ok["within_after_s"].isna() & ok["ate_raw"].notna()).sum())
        for m in _summarised(df):
            v = ok[m].dropna()
            rec[f"{m}_median"] = float(v.median()) if len(v) else float("nan")
            rec[f"{m}_min"] = float(v.min()) if len(v) else float("nan")
            rec[f"{m}_max"] = float(v.max()) if len(v) else float("nan")
        records.append(rec)
    return pd.DataFrame.from_records(records)


def combination_label(rec: Mapping[str, object], setting_keys: Sequence[str]) -> str:
    """``log`` or ``log: key=value, ...`` for a row of the table or of the summary."""
    values = {k: rec[k] for k in setting_keys}
    return f"{rec['log']}: {settings_text(values)}" if values else str(rec["log"])


def filters_run(df: pd.DataFrame, folder: str | Path) -> dict[str, str]:
    """The filter each ok run of the table ran (``filter.filter`` of its run.json, e.g. rbpf
    where the setting was auto), by run folder; runs without that record left out."""
    import json

    found = {}
    for run_dir in df.loc[df["status"] == "ok", "run_dir"].dropna():
        with contextlib.suppress(OSError, ValueError, TypeError, AttributeError, KeyError):
            name = json.loads((Path(folder) / str(run_dir) / "run.json").read_text())["filter"]["filter"]
            found[str(run_dir)] = str(name)
    return found


SHARES = ("map_agreement",)  # metrics between 0 and 1: drawn on that whole axis


def plot_summary(df: pd.DataFrame, setting_keys: Sequence[str], path: str | Path) -> Path | None:
    """A box plot per summary metric (of those the table has, see :func:`summarize`) that
    any ok run has, one box per log × setting combination over the seeds; None (and no
    file) without ok runs. Each
    box's label says which filter ran (from the runs' run.json, beside ``path``) when the
    settings do not; every axis starts at 0, so a box's height is not exaggerated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = df[df["status"] == "ok"]
    metrics = [m for m in _summarised(df) if ok[m].notna().any()]
    if not metrics:
        with contextlib.suppress(FileNotFoundError):  # not the picture of an earlier table
            Path(path).unlink()
        return None
    keys = ["log", *setting_keys]
    groups = [
        (dict(zip(keys, g if isinstance(g, tuple) else (g,))), part)
        for g, part in ok.groupby(keys, sort=False, dropna=False)
    ]
    ran = filters_run(ok, Path(path).parent) if "filter" not in setting_keys else {}
    labels = []
    for g, part in groups:
        label = combination_label(g, setting_keys).replace(": ", "\n").replace(", ", "\n")
        names = sorted({ran[str(d)] for d in part["run_dir"].dropna() if str(d) in ran})
        if names:
            label += "\nfilter=" + "/".join(names)
        labels.append(label)
    ncols = min(3, len(metrics))
    nrows = -(-len(metrics) // ncols)
    longest = max(len(line) for label in labels for line in label.splitlines())
    width = max(4.0, max(1.0, 0.065 * longest + 0.2) * len(groups) + 1.0)  # room for the 7 pt labels
    fig, axes = plt.subplots(nrows, ncols, figsize=(ncols * width, nrows * 4.2 + 0.6), squeeze=False)
    for ax, m in zip(axes.flat, metrics):
        data = [part[m].dropna().to_numpy() for _, part in groups]
        pos = [i + 1 for i, d in enumerate(data) if len(d)]
        ax.boxplot([d for d in data if len(d)], positions=pos, widths=0.6, showfliers=False)
        for p, d in zip(pos, [d for d in data if len(d)]):  # every run, outliers included
            ax.scatter([p] * len(d), d, s=10, color="tab:blue", alpha=0.6, zorder=3)
        ax.set_xticks(range(1, len(groups) + 1))
        ax.set_xticklabels(labels, fontsize=7, rotation=90 if len(groups) > 8 else 0, ha="center")
        ax.set_xlim(0.4, len(groups) + 0.6)
        top = max(float(np.nanmax(np.concatenate(data))) if any(len(d) for d in data) else 1.0, 1e-9)
        flat = top <= 1e-9  # every run 0 (a localization that settled at once): an axis of 0-1, not 0-1e-9
        ax.set_ylim(0.0, 1.0 if flat or (m in SHARES and top <= 1.0) else 1.08 * top)  # from 0: no exaggerated gaps
        ax.set_title(heading(m), fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(metrics) :]:
        ax.set_visible(False)
    seeds = ok.groupby(keys, sort=False, dropna=False)["seed"].nunique()
    lo, hi = int(seeds.min()), int(seeds.max())
    fig.suptitle(
        f"pfslam sweep {Path(path).parent.name}: {len(ok)} ok runs, {len(groups)} combinations; "
        f"boxes over {lo if lo == hi else f'{lo}-{hi}'} seeds (dots: each run)",
        fontsize=11,
    )
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.35 / (nrows * 4.2 + 0.6)))  # the title above the panels' own
    out = Path(path)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
