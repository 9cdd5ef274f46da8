"""How honest each method's tracks are in a finished study, with the tails in view.

One markdown row per method (all targets): mean run RMSE with its 95 % t-interval, the
median run RMSE, the ANEES over all target-steps, the ANEES without the run of largest
ANEES, the median and the 95 % t-interval over runs of the run ANEES, the share of
target-steps with NEES above 13.28 (the 99 % point of chi-square(4)) and the diverged runs
(largest position error above 300 m), from ``sensorplan.study.metrics`` as in the report.

    python scripts/honest_summary.py STUDY_DIR
"""

from __future__ import annotations

import argparse

import numpy as np

from sensorplan.errors import ConfigError
from sensorplan.study.metrics import NEES_HIGH, run_metrics, t_interval
from sensorplan.study.storage import load_study_dir

#: A run whose largest position error exceeds this has diverged (as in the report).
DIVERGED_M = 300.0


def rows(study_dir: str) -> list[str]:
    tables = load_study_dir(study_dir)
    steps = tables.steps[tables.steps["step"] >= 1]
    rm = run_metrics(tables)
    rm = rm[rm["kind"] == "all"]
    out = ["| method | RMSE mean (m) | median | ANEES | without the worst run | run ANEES: "
           "median; mean [95 %] | NEES > 13.28 | diverged |",
           "|---|--:|--:|--:|--:|--:|--:|--:|"]
    for m in tables.study.method_names:
        g = steps[steps["method"] == m]
        r = rm[rm["method"] == m]["rmse"].to_numpy(float)
        mean, lo, hi = t_interval(r)
        per_run = g.groupby("run", observed=True)["nees"].mean()
        worst = per_run.idxmax()
        rmean, rlo, rhi = t_interval(per_run.to_numpy(float))
        diverged = int((g.groupby("run", observed=True)["error"].max() > DIVERGED_M).sum())
        out.append(
            f"| {m} | {mean:.1f} [{lo:.1f}, {hi:.1f}] | {np.median(r):.1f} | "
            f"{g['nees'].mean():.2f} | {g[g['run'] != worst]['nees'].mean():.2f} | "
            f"{per_run.median():.2f}; {rmean:.2f} [{rlo:.2f}, {rhi:.2f}] | "
            f"{100 * (g['nees'] > NEES_HIGH).mean():.1f} % | {diverged} of {len(r)} |")
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study_dir")
    args = parser.parse_args(argv)
    try:
        print("\n".join(rows(args.study_dir)))
    except ConfigError as err:
        parser.error(str(err))


if __name__ == "__main__":
    main()
