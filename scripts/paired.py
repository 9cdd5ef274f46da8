"""Paired differences between any two methods of a finished study.

``sensorplan report`` compares each method with myopic and with random. A study often asks
more (detection-aware against detection-ignoring planning, one objective against another):
this prints, for each ``A - B`` given, one markdown row per target kind with the paired
mean difference of the run RMSE and its 95 % t-interval, the median with its order-statistic
interval, the share of runs where A was lower, and each side's diverged runs (largest error
above 300 m), from ``sensorplan.study.metrics`` as in the report.

    python scripts/paired.py STUDY_DIR "A - B" ["C - D" ...]
"""

from __future__ import annotations

import argparse

from sensorplan.errors import ConfigError
from sensorplan.study.metrics import paired_differences, run_metrics
from sensorplan.study.storage import load_study_dir

#: A run whose largest position error exceeds this has diverged (as in the report).
DIVERGED_M = 300.0


def _pair(text: str) -> tuple[str, str]:
    a, sep, b = text.partition(" - ")
    if not sep or not a.strip() or not b.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write a pair as 'A - B'")
    return a.strip(), b.strip()


def rows(study_dir: str, pairs: list[tuple[str, str]]) -> list[str]:
    """The markdown table, header first."""
    tables = load_study_dir(study_dir)
    names = [m.name for m in tables.study.methods]
    for a, b in pairs:
        for name in (a, b):
            if name not in names:
                raise ConfigError("pairs", f"{name!r} is not a method of {study_dir} "
                                           f"(methods: {', '.join(names)})")
    metrics = run_metrics(tables)
    d = paired_differences(metrics, tables.study, pairs=pairs)
    worst = tables.steps[tables.steps["step"] >= 1].groupby(
        ["method", "run"], observed=True)["error"].max()
    diverged = (worst > DIVERGED_M).groupby(level="method", observed=True).sum()
    out = ["| A - B | kind | n | mean (m) | median (m) | A better | diverged A / B |",
           "|---|---|--:|--:|--:|--:|--:|"]
    for r in d.itertuples():
        out.append(f"| {r.method} - {r.reference} | {r.kind} | {r.n} | "
                   f"{r.mean:+.1f} [{r.mean_lo:+.1f}, {r.mean_hi:+.1f}] | "
                   f"{r.median:+.1f} [{r.median_lo:+.1f}, {r.median_hi:+.1f}] | "
                   f"{100 * r.better_share:.0f} % | "
                   f"{int(diverged.get(r.method, 0))} / {int(diverged.get(r.reference, 0))} |")
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study_dir")
    parser.add_argument("pairs", nargs="+", type=_pair, metavar="'A - B'")
    args = parser.parse_args(argv)
    try:
        print("\n".join(rows(args.study_dir, args.pairs)))
    except ConfigError as err:
        parser.error(str(err))


if __name__ == "__main__":
    main()
