"""Before and after: one method's runs under the old and the new code, side by side.

For each study directory pair (BEFORE, AFTER) of the same study file and seed, prints one
markdown row per method present in both: mean position RMSE over all targets with its 95 %
t-interval, the median, ANEES, the share of target-steps with NEES above 13.28, the number
of diverged runs (largest error above 300 m), and the paired mean difference after - before
over the runs both finished (same seed: same true trajectories). Metrics come from
``sensorplan.study.metrics``, as in ``sensorplan report``.

    python scripts/before_after.py BEFORE_DIR AFTER_DIR [BEFORE_DIR AFTER_DIR ...]
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from sensorplan.errors import ConfigError
from sensorplan.study.metrics import consistency, run_metrics, t_interval
from sensorplan.study.storage import StudyTables
from sensorplan.study.storage import load_study_dir as load_tables


def _before(before: str, new: StudyTables) -> StudyTables:
    """The BEFORE directory's tables; an older directory format is read from its
    steps.parquet directly (the columns these metrics use have not changed)."""
    try:
        return load_tables(before)
    except ConfigError:
        import pandas as pd

        steps = pd.read_parquet(Path(before) / "steps.parquet")
        steps["kind"] = steps["kind"].astype(new.steps["kind"].dtype)
        return dataclasses.replace(new, steps=steps)


def table(before: str, after: str) -> None:
    new = load_tables(after)
    old = _before(before, new)
    old_methods = set(old.steps["method"].astype(str).unique())
    rm_old, rm_new = run_metrics(old), run_metrics(new)
    c_old, c_new = consistency(old), consistency(new)
    print(f"\n{before} -> {after}\n")
    print("| method | RMSE mean before | after | median before | after | ANEES before | after "
          "| NEES > 13.28 before | after | diverged before | after | after - before (paired) |")
    print("|---|" + "--:|" * 11)
    for method in new.study.method_names:
        if method not in old_methods:
            continue
        a = rm_old[(rm_old.method == method) & (rm_old.kind == "all")].set_index("run").rmse
        b = rm_new[(rm_new.method == method) & (rm_new.kind == "all")].set_index("run").rmse
        ca = c_old[(c_old.method == method) & (c_old.kind == "all")].iloc[0]
        cb = c_new[(c_new.method == method) & (c_new.kind == "all")].iloc[0]
        both = a.index.intersection(b.index)
        d, lo, hi = t_interval((b[both] - a[both]).to_numpy(float))
        ma, la, ha = t_interval(a.to_numpy(float))
        mb, lb, hb = t_interval(b.to_numpy(float))
        print(f"| {method} | {ma:.1f} [{la:.1f}, {ha:.1f}] | {mb:.1f} [{lb:.1f}, {hb:.1f}] "
              f"| {a.median():.1f} | {b.median():.1f} | {ca.anees:.3g} | {cb.anees:.3g} "
              f"| {100 * ca.high_share:.1f} % | {100 * cb.high_share:.1f} % "
              f"| {ca.diverged} of {ca.runs} | {cb.diverged} of {cb.runs} "
              f"| {d:+.1f} [{lo:+.1f}, {hi:+.1f}] (n = {both.size}) |")


def main(argv: list[str]) -> int:
    if len(argv) < 2 or len(argv) % 2:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    try:
        for before, after in zip(argv[::2], argv[1::2]):
            table(before, after)
    except (ConfigError, FileNotFoundError) as err:
        print(f"before_after.py: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
