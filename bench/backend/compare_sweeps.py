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

    def loops(r: pd.Series) -> tuple[float, float, object]:
        info = json.loads((Path(r["folder"]) / r["run_dir"] / "run.json").read_text())
        le = info.get("metrics", {}).get("loop_edges", {})
        kept = info.get("backend", {}).get("kept", True) if backend == "graph" else None
        return le.get("in_graph", float("nan")), le.get("off", float("nan")), kept

    if backend == "graph":
        d[["loops", "off", "kept"]] = d.apply(lambda r: pd.Series(loops(r)), axis=1)
    return d.set_index(["log", "seed"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--none", nargs="+", required=True, help="sweep folders with backend=none runs")
    ap.add_argument("--before", nargs="+", required=True, help="sweep folders with the old backend=graph runs")
    ap.add_argument("--after", nargs="+", required=True, help="sweep folders with the new backend=graph runs")
    ap.add_argument("--metric", default="ate_aligned")
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


if __name__ == "__main__":
    main()
