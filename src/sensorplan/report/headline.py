"""The report's headline: the best method, by how much, and whether looking ahead paid.

Computed from the report's statistics (:mod:`sensorplan.study.metrics`) over all targets
(the scenario's only kind when it has one):

- the best method by mean RMSE (by mean GOSPA in a study of changing sets), with its 95 %
  t-interval;
- its paired difference (run by run) against the runner-up and against its random
  reference, each with a 95 % paired t-interval;
- the best method with horizon K > 1 that has a myopic reference, and its paired
  difference against that myopic method: lookahead *paid* if the interval lies below zero,
  *lost* if above, and is *inconclusive* otherwise. When it did not pay, one sentence says
  that this is a finding and points to docs/results.md.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..study.metrics import kinds_with_all, references, t_interval
from ..study.model import Study

#: Fewer runs than this: intervals are flagged as unreliable.
SMALL_SAMPLE = 10


@dataclass(frozen=True)
class Interval:
    """A mean with its 95 % interval and the number of runs it is from."""

    mean: float
    lo: float
    hi: float
    n: int

    def text(self, signed: bool = False, digits: int = 1) -> str:
        sign = "+" if signed else ""
        # No "-0.0": a mean that rounds to zero is shown as zero.
        mean = 0.0 if abs(self.mean) < 0.5 * 10.0 ** -digits else self.mean
        m = f"{mean:{sign}.{digits}f}"
        if not (math.isfinite(self.lo) and math.isfinite(self.hi)):
            return f"{m} m"
        return f"{m} m [{self.lo:.{digits}f}, {self.hi:.{digits}f}]"

    @property
    def below_zero(self) -> bool:
        return math.isfinite(self.hi) and self.hi < 0

    @property
    def above_zero(self) -> bool:
        return math.isfinite(self.lo) and self.lo > 0


@dataclass(frozen=True)
class Headline:
    """What the headline says; None where the study has no such method."""

    kind: str
    best: str
    best_rmse: Interval
    runner_up: str | None
    vs_runner_up: Interval | None            # best minus runner-up (<= 0 in the mean)
    random: str | None
    vs_random: Interval | None               # best minus random
    lookahead: str | None                    # the best K > 1 method with a myopic reference
    myopic: str | None
    vs_myopic: Interval | None               # lookahead minus myopic
    better_share: float = math.nan           # runs in which lookahead beat myopic
    small_sample: bool = False
    metric: str = "rmse"                     # what it judges by: rmse or gospa

    @property
    def verdict(self) -> str | None:
        """``paid``, ``lost``, ``inconclusive`` or None (no K > 1 method to judge)."""
        if self.vs_myopic is None:
            return None
        if self.vs_myopic.below_zero:
            return "paid"
        if self.vs_myopic.above_zero:
            return "lost"
        return "inconclusive"


def _paired(wide: Any, a: str, b: str) -> Interval:
    """Mean [95 % paired t-interval] of ``a - b`` over the runs both finished."""
    both = wide[[a, b]].dropna()
    d = (both[a] - both[b]).to_numpy(float)
    mean, lo, hi = t_interval(d)
    return Interval(float(mean), float(lo), float(hi), int(d.size))


def _flag(summary_rows: Any) -> bool:
    """Whether the summary flags its intervals as from a small sample: the metrics'
    ``small_sample`` column if it has one, else fewer than :data:`SMALL_SAMPLE` runs."""
    if "small_sample" in summary_rows:
        return bool(np.any(summary_rows["small_sample"].to_numpy(bool)))
    return bool(np.any(summary_rows["n"].to_numpy() < SMALL_SAMPLE))


def headline(study: Study, metrics: Any, rmse: Any, diffs: Any,
             column: str = "rmse") -> Headline:
    """The headline of a study from :func:`~sensorplan.study.metrics.run_metrics`,
    its RMSE :func:`~sensorplan.study.metrics.summary` and
    :func:`~sensorplan.study.metrics.paired_differences`; with ``column="gospa"``, from
    :func:`~sensorplan.study.metrics.gospa_run_metrics` and its summary and differences
    (a study of changing sets is judged by GOSPA)."""
    kind = kinds_with_all(study)[-1]            # "all", or the only kind
    r = rmse[rmse["kind"] == kind].set_index("method")
    r = r.loc[[n for n in study.method_names if n in r.index]]
    order = r["mean"].astype(float).sort_values(kind="stable")
    best = str(order.index[0])
    runner = str(order.index[1]) if len(order) > 1 else None
    m = metrics[metrics["kind"] == kind]
    wide = m.pivot_table(index="run", columns="method", values=column, observed=True)
    b = r.loc[best]
    refs = references(study)
    planners = {x.name: x.settings for x in study.methods}
    rnd = refs[best]["random"]
    if rnd is None and planners[best].planner != "random":
        rnd = next((n for n in study.method_names if planners[n].planner == "random"), None)

    look = [n for n in order.index if planners[n].horizon > 1 and refs[n]["myopic"]]
    look_name = str(look[0]) if look else None
    vs_myopic = None
    share = math.nan
    myopic = refs[look_name]["myopic"] if look_name else None
    if look_name is not None and len(diffs):
        d = diffs[(diffs["method"] == look_name) & (diffs["against"] == "myopic")
                  & (diffs["kind"].astype(str) == kind)]
        if len(d):
            row = d.iloc[0]
            vs_myopic = Interval(float(row["mean"]), float(row["mean_lo"]),
                                 float(row["mean_hi"]), int(row["n"]))
            share = float(row["better_share"])
    return Headline(
        kind=kind, best=best,
        best_rmse=Interval(float(b["mean"]), float(b["mean_lo"]), float(b["mean_hi"]),
                           int(b["n"])),
        runner_up=runner, vs_runner_up=_paired(wide, best, runner) if runner else None,
        random=rnd, vs_random=_paired(wide, best, rnd) if rnd else None,
        lookahead=look_name, myopic=myopic, vs_myopic=vs_myopic, better_share=share,
        small_sample=_flag(r), metric=column)


def results_link(report_dir: Path) -> str | None:
    """Relative path from the report to docs/results.md when the package runs from a
    source checkout that has it (None for an installed package)."""
    docs = Path(__file__).resolve().parents[3] / "docs" / "results.md"
    if not docs.exists():
        return None
    try:
        return Path(os.path.relpath(docs, report_dir.resolve())).as_posix()
    except ValueError:                  # another drive (Windows)
        return docs.as_uri()


def headline_paragraphs(h: Headline, link: str | None) -> list[str]:
    """The headline as paragraphs of inline markdown (``**bold**``, ``[text](href)``)."""
    over = "all targets" if h.kind == "all" else f"{h.kind} targets"
    n = h.best_rmse.n
    what = ("mean GOSPA (each run's mean over its steps)" if h.metric == "gospa"
            else f"mean position RMSE over {over}")
    first = (f"**Best method: {h.best}**, {what} "
             f"{h.best_rmse.text()} (95 % t-interval, {n} paired run{'' if n == 1 else 's'}).")
    parts = []
    if h.runner_up is not None and h.vs_runner_up is not None:
        parts.append(f"{h.vs_runner_up.text(True)} against the runner-up, {h.runner_up} "
                     f"({_significance(h.vs_runner_up)})")
    if h.random is not None and h.vs_random is not None:
        parts.append(f"{h.vs_random.text(True)} against {h.random} "
                     f"({_significance(h.vs_random)})")
    if parts:
        first += (" Paired differences per run (best minus other, 95 % paired t-interval): "
                  + "; ".join(parts) + ".")
    if h.small_sample:
        first += f" (n < {SMALL_SAMPLE}: intervals unreliable.)"
    out = [first]
    verdict = h.verdict
    if verdict is None:
        out.append("Lookahead: the study has no method with horizon K > 1 and a myopic "
                   "reference, so whether looking ahead pays is not tested here.")
        return out
    assert h.vs_myopic is not None
    share = ("" if not math.isfinite(h.better_share)
             else f", better in {100 * h.better_share:.0f} % of runs")
    diff = f"{h.lookahead} \u2212 {h.myopic} = {h.vs_myopic.text(True)} (paired{share})"
    if verdict == "paid":
        out.append(f"**Lookahead paid:** the best K > 1 method beats myopic planning "
                   f"significantly, {diff}.")
        return out
    if verdict == "lost":
        out.append(f"**Lookahead did not pay:** the best K > 1 method is significantly "
                   f"worse than myopic planning, {diff}.")
    else:
        out.append(f"**Lookahead did not pay here:** the best K > 1 method is not "
                   f"significantly better than myopic planning, {diff}.")
    where = f"[docs/results.md]({link})" if link else \
        "docs/results.md (in the sensorplan source)"
    out.append("That is a finding, not a bug: in scenarios like the paper's (fast platforms, "
               "ideal detection, open ground) myopic planning already measures on most "
               "sensor-steps, which leaves little for a longer horizon to win. "
               f"{where} maps where lookahead does pay, on 100 paired runs per condition "
               "(\"Where looking ahead pays\"): when sensors must first reposition to see "
               "(slow platforms, towns that hide targets, blind discs), most with the "
               "cumulative objective and a decision every step.")
    return out


def _significance(iv: Interval) -> str:
    if iv.below_zero or iv.above_zero:
        return "significant"
    if not (math.isfinite(iv.lo) and math.isfinite(iv.hi)):
        return "no interval"
    return "not significant"
