"""Per log and seed, the back end before and after a change, beside the filter alone: aligned
ATE, the loops in the graph that are off the truth (run.json's metrics.loop_edges), the map
agreement, and whether the back end's answer was kept. Reads the results.csv of `pfslam
sweep` runs (several folders of one side are pooled, e.g. one sweep per seed).

    python bench/backend/compare_sweeps.py --none out/before_backend --before out/before_backend \
        --after out/after_backend [--markdown]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pandas as pd


def read(folders: list[str], backend: str) -> pd.DataFrame:
    rows = []
    for f in folders:
        for csv in sorted(Path(f).glob("**/results.csv")):
            d = pd.read_csv(csv)
            d = d[(d["backend"] == backend) & (d["status"] == "ok")].copy()
            d["folder"] = str(csv.parent)
            rows.append(d)
    if not rows:
        return pd.DataFrame(columns=["log", "seed"])
    d = pd.concat(rows)

    def loops(r: pd.Series) -> tuple[float, float, float, object]:
        info = json.loads((Path(r["folder"]) / r["run_dir"] / "run.json").read_text())
        le = info.get("metrics", {}).get("loop_edges", {})
        kept = info.get("backend", {}).get("kept", True) if backend == "graph" else None
        nan = float("nan")
        return le.get("solved", nan), le.get("solved_off", nan), le.get("solved_off_beyond_own", nan), kept

    if backend == "graph":
        d[["loops", "off", "off_sure", "kept"]] = d.apply(lambda r: pd.Series(loops(r)), axis=1)
    return d.set_index(["log", "seed"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--none", nargs="+", required=True, help="sweep folders with backend=none runs")
    ap.add_argument("--before", nargs="+", required=True, help="sweep folders with the old backend=graph runs")
    ap.add_argument("--after", nargs="+", required=True, help="sweep folders with the new backend=graph runs")
    ap.add_argument("--metric", default="ate_aligned")
    ap.add_argument("--summary", help="write the per-log summary (and every walk's figures) to this JSON file")
    args = ap.parse_args()
    none = read(args.none, "none")
    before = read(args.before, "graph")
    after = read(args.after, "graph")
    m = args.metric
    t = pd.DataFrame({"none": none[m], "before": before[m], "after": after[m]})
    t["agree none"] = none["map_agreement"]
    t["agree before"] = before["map_agreement"]
    t["agree after"] = after["map_agreement"]
    for side, d in (("before", before), ("after", after)):
        if "off" in d:
            t[f"off/loops {side}"] = [
                f"{int(o)}/{int(n)}" if pd.notna(o) else "-"
                for o, n in zip(d["off"].reindex(t.index), d["loops"].reindex(t.index))
            ]
    if "kept" in after:
        t["kept"] = after["kept"].reindex(t.index)
    t["after - none (mm)"] = 1000 * (t["after"] - t["none"])
    pd.set_option("display.width", 200)
    print(t.round(3).to_string())
    g = t.groupby(level=0)
    print()
    print(g[["none", "before", "after"]].agg(["min", "max"]).round(3).to_string())
    out: dict[str, object] = {}
    for log, s in g:
        row: dict[str, object] = {"walks": int(s["none"].notna().sum()), "median_none": float(s["none"].median())}
        for side, d in (("before", before), ("after", after)):
            x = s[side]
            worse = 1000 * (x - s["none"])
            off = d["off"].reindex(s.index) if "off" in d else pd.Series(dtype=float)
            sure = d["off_sure"].reindex(s.index) if "off_sure" in d else pd.Series(dtype=float)
            row[side] = {
                "median": float(x.median()),
                "better_than_none": int((worse < 0).sum()),
                "worse_than_none_by_5mm": int((worse > 5).sum()),
                "walks_with_loops_off": int((off.fillna(0) > 0).sum()),
                "loops_off": int(off.fillna(0).sum()),
                "loops_off_beyond_own": int(sure.fillna(0).sum()) if sure.notna().any() else None,
            }
        out[str(log)] = row
    print(json.dumps(out, indent=1))
    if args.summary:
        walks = {
            f"{k[0]} {k[1]}": {
                c: (None if pd.isna(v) else float(v)) for c, v in r.items() if c in ("none", "before", "after")
            }
            for k, r in t.iterrows()
        }
        Path(args.summary).write_text(json.dumps({"summary": out, "walks": walks}, indent=1) + "\n")


if __name__ == "__main__":
    main()
