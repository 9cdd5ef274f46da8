"""Apply the tracker sweep's selection rule (stated in studies/tracker_sweep.toml) to its
results and print the table behind the choice.

    python scripts/select_tracker.py runs/tracker_sweep
"""

from __future__ import annotations

import argparse
from typing import Any

import pandas as pd

from sensorplan.errors import ConfigError
from sensorplan.study import consistency, load_study_dir, run_metrics, summary

MAX_ANEES = 6.0
MAX_HIGH_SHARE = 0.05
TIE = 0.02


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study_dir", help="the tracker sweep's study directory")
    args = parser.parse_args(argv)
    try:
        choose(load_study_dir(args.study_dir))
    except ConfigError as err:
        parser.error(str(err))


def choose(t: Any) -> None:
    """Print the sweep's table and the configuration its rule chooses."""
    rmse = summary(run_metrics(t), "rmse")
    rmse = rmse[rmse["kind"] == "all"].set_index("method")
    honest = consistency(t)
    honest = honest[honest["kind"] == "all"].set_index("method")
    rows = []
    for name in t.study.method_names:
        config, planner = name.split("/")
        rows.append(dict(config=config, planner=planner, rmse=rmse.loc[name, "mean"],
                         rmse_median=rmse.loc[name, "median"],
                         anees=honest.loc[name, "anees"],
                         high=honest.loc[name, "high_share"],
                         diverged=honest.loc[name, "diverged"]))
    df = pd.DataFrame(rows)
    wide = df.pivot(index="config", columns="planner")
    wide.columns = [f"{a}_{b}" for a, b in wide.columns]
    planners = sorted(df["planner"].unique())
    wide["rmse_avg"] = wide[[f"rmse_{p}" for p in planners]].mean(axis=1)
    wide["worst_anees"] = wide[[f"anees_{p}" for p in planners]].max(axis=1)
    wide["ok"] = ((wide[[f"anees_{p}" for p in planners]] <= MAX_ANEES).all(axis=1)
                  & (wide[[f"high_{p}" for p in planners]] <= MAX_HIGH_SHARE).all(axis=1))
    pd.set_option("display.width", 200)
    print(wide.sort_values("rmse_avg").round(3).to_string())
    candidates = wide[wide["ok"] & (wide.index != "plain")]
    if candidates.empty:
        choice = wide.drop(index="plain", errors="ignore")["worst_anees"].idxmin()
        print(f"\nno candidate meets the consistency bounds; smallest worst ANEES: {choice}")
        return
    best = candidates["rmse_avg"].min()
    tied = candidates[candidates["rmse_avg"] <= best * (1 + TIE)]

    def simplicity(config: str) -> tuple[int, float]:
        model = 0 if config.startswith("cv") else 1
        return model, float(config.lstrip("cvim"))

    choice = min(tied.index, key=simplicity)
    print(f"\nqualifying: {', '.join(candidates.index)}")
    print(f"lowest mean RMSE {best:.2f} m; within {TIE:.0%}: {', '.join(tied.index)}")
    print(f"default: {choice}")


if __name__ == "__main__":
    main()
