"""Metrics and statistics of runs and studies: the one place where errors become numbers.

Position RMSE per run, lost target-steps (error above :data:`LOST_THRESHOLD`), across-run
means with t-intervals, medians with order-statistic intervals, paired differences against
reference methods, RMSE over time and planning/sensing summaries, all functions of a
study's tidy tables; :func:`episode_errors` gives the same per-target numbers for one
episode (``sensorplan simulate``). The report only draws and formats these. This module
never imports matplotlib.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .._types import FloatArray
from ..simulation.settings import RunSettings
from .model import Method, Study

if TYPE_CHECKING:  # pragma: no cover
    from ..simulation.run import Episode
    from .storage import StudyTables

#: Position error above which a target-step counts as lost (m).
LOST_THRESHOLD = 50.0
#: A run whose largest position error exceeds this (m) has diverged.
DIVERGED_THRESHOLD = 300.0
#: State dimension of the NEES (x, y, vx, vy): a consistent filter's NEES is chi-square(4).
NEES_DOF = 4
#: NEES above the 99 % point of chi-square(4) (13.28) is counted as inconsistent.
NEES_HIGH = 13.276704135987622
#: Confidence level of every interval.
LEVEL = 0.95


def nees_band(n: Any, level: float = LEVEL, dof: int = NEES_DOF) -> tuple[Any, Any]:
    """Two-sided chi-square band of the average of ``n`` NEES values of a consistent filter.

    The sum of n independent chi-square(dof) values is chi-square(n dof), so the average lies
    in ``[chi2.ppf(a, n dof) / n, chi2.ppf(1 - a, n dof) / n]``, ``a = (1 - level) / 2``,
    with probability ``level``.
    """
    from scipy import stats

    n = np.asarray(n, dtype=float)
    a = (1.0 - level) / 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        return (stats.chi2.ppf(a, n * dof) / n, stats.chi2.ppf(1.0 - a, n * dof) / n)


def lost(error: Any) -> Any:
    """Whether each target-step is lost: position error (m) > :data:`LOST_THRESHOLD`."""
    return error > LOST_THRESHOLD


@dataclass(frozen=True)
class ErrorRow:
    """Position errors over steps 1..S of one target or a group of targets (m).

    ``target`` is the index, or ``"all"`` for every target of ``kind`` (``"all"`` kinds:
    every target); ``lost_share`` is the share of target-steps lost (for a multi-target
    tracker, of live target-steps without an assigned track); ``measured`` counts
    the target-steps with at least one measurement; ``anees`` is the average NEES (4 for an
    honest filter) and ``restarts`` counts the track restarts.
    """

    target: str
    kind: str
    rmse: float
    mean: float
    final: float
    lost_share: float
    measured: int
    anees: float = math.nan
    restarts: int = 0


def episode_errors(episode: Episode) -> list[ErrorRow]:
    """Per target, then per target kind (and all targets when there are several kinds).

    For a multi-target tracker the errors are those of the track assigned to each live
    target (:func:`~sensorplan.study.set_metrics.with_assigned_tracks`), over the steps it
    had one.
    """
    from .set_metrics import with_assigned_tracks

    episode = with_assigned_tracks(episode)
    err = np.asarray(episode.error)[1:]                                # (S, M)
    measured = np.any(np.asarray(episode.measured)[1:], axis=2)       # (S, M)
    nees = np.asarray(episode.nees)[1:]
    restarted = np.asarray(episode.restarted)[1:]
    kinds = list(episode.target_kinds)
    if episode.settings.tracker.kind == "known":
        gone = lost(err).astype(float)
    else:
        # A live target without an assigned track is lost (its error is NaN); an assigned
        # track lies within the run's GOSPA cut-off, whatever LOST_THRESHOLD says (the
        # studies' run_metrics count the same). A target not alive is no target-step.
        alive = np.asarray(episode.alive, dtype=bool)[1:]
        gone = np.where(alive, np.isnan(err), np.nan)

    def row(target: str, kind: str, idx: list[int]) -> ErrorRow:
        e = err[:, idx]
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)        # a target never assigned
            return ErrorRow(target, kind, float(np.sqrt(np.nanmean(e ** 2))),
                            float(np.nanmean(e)), float(np.nanmean(e[-1])),
                            float(np.nanmean(gone[:, idx])), int(measured[:, idx].sum()),
                            float(np.nanmean(nees[:, idx])), int(restarted[:, idx].sum()))

    rows = [row(str(j), kind, [j]) for j, kind in enumerate(kinds)]
    for kind in _with_all(kinds):
        rows.append(row("all", kind, [j for j, k in enumerate(kinds) if kind in (k, "all")]))
    return rows


def episode_consistency(episode: Episode) -> dict[str, float]:
    """ANEES over steps 1..S and targets, its band, the share above :data:`NEES_HIGH`, and
    the track restarts and map corrections of one episode (for a multi-target tracker, of
    the tracks assigned to live targets)."""
    from .set_metrics import with_assigned_tracks

    nees = np.asarray(with_assigned_tracks(episode).nees)[1:]
    nees = nees[np.isfinite(nees)]
    lo, hi = nees_band(nees.size)
    return dict(anees=float(nees.mean()), band_lo=float(lo), band_hi=float(hi),
                high_share=float((nees > NEES_HIGH).mean()),
                restarts=int(np.asarray(episode.restarted).sum()),
                map_corrections=int(np.asarray(episode.map_corrected).sum()))


def t_interval(values: Any, level: float = LEVEL, axis: int = 0
               ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean and two-sided t confidence interval of the mean along ``axis``.

    ``mean -+ t_{(1+level)/2, n-1} * s / sqrt(n)`` with the sample standard deviation
    ``s`` (ddof = 1): ``scipy.stats.t.interval(level, n - 1, loc=mean, scale=s/sqrt(n))``.
    NaNs are ignored; bounds are NaN with fewer than 2 values.

    Returns
    -------
    mean, lo, hi : arrays (``values`` with ``axis`` removed; 0-d for 1-D input)
    """
    from scipy import stats

    x = np.asarray(values, dtype=float)
    ok = ~np.isnan(x)
    n = ok.sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, np.nansum(x, axis=axis) / np.maximum(n, 1), np.nan)
        dev = np.where(ok, x - np.expand_dims(mean, axis), 0.0)
        var = (dev ** 2).sum(axis=axis) / np.maximum(n - 1, 1)
        sem = np.sqrt(var / np.maximum(n, 1))
        tq = stats.t.ppf(0.5 + level / 2, np.maximum(n - 1, 1))
        half = np.where(n >= 2, tq * sem, np.nan)
    return mean, mean - half, mean + half


def median_interval(values: Any, level: float = LEVEL) -> tuple[float, float, float]:
    """Median and a distribution-free confidence interval for it (order statistics).

    With ``B ~ Binomial(n, 1/2)`` and ``l`` the largest integer with
    ``P(B <= l - 1) <= (1 - level) / 2``, the interval ``[x_(l), x_(n-l+1)]`` (1-based order
    statistics) covers the population median with probability ``1 - 2 P(B <= l - 1) >=
    level``. Bounds are NaN when ``n`` is too small for the level (n < 6 at 95 %).
    """
    from scipy import stats

    x = np.sort(np.asarray(values, dtype=float)[~np.isnan(np.asarray(values, dtype=float))])
    n = x.size
    if n == 0:
        return math.nan, math.nan, math.nan
    med = float(np.median(x))
    lo_rank = int(stats.binom.ppf((1 - level) / 2, n, 0.5))
    # ppf gives the smallest l with P(B <= l) >= alpha/2, so P(B <= l - 1) < alpha/2.
    if lo_rank < 1:
        return med, math.nan, math.nan
    return med, float(x[lo_rank - 1]), float(x[n - lo_rank])


def kinds_with_all(study: Study) -> list[str]:
    """Target kinds of the scenario in first-seen order, then ``"all"`` if several."""
    return _with_all(study.scenario.target_kinds)


def _with_all(target_kinds: Any) -> list[str]:
    kinds = list(dict.fromkeys(target_kinds))
    return kinds + ["all"] if len(kinds) > 1 else kinds


def set_methods(study: Study) -> list[str]:
    """The methods whose tracker is a multi-target one (its tracks are not the targets)."""
    return [m.name for m in study.methods if m.settings.tracker.kind != "known"]


def run_metrics(tables: StudyTables) -> Any:
    """Per (method, run, kind) metrics over steps 1..S.

    Columns: method, run, kind (each target kind and ``all``), rmse (m; ``sqrt`` of the mean
    over steps 1..S and the kind's targets of error^2), mean_error (m), lost_share (share of
    those target-steps with error > :data:`LOST_THRESHOLD`), measured_share (share with at
    least one measurement), negative_share (share that got a missed-look update).

    For a multi-target tracker (:func:`set_methods`) the errors are those of the assigned
    tracks, so rmse and mean_error are over the target-steps that have one, and lost_share
    is the share of target-steps without one (GOSPA's missed part): an assigned track is
    within the cut-off, so the error rule would count none of them.
    """
    import pandas as pd

    d = tables.steps[tables.steps["step"] >= 1]
    gone = lost(d["error"])
    sets = d["method"].isin(set_methods(tables.study))
    if sets.any():
        gone = gone.where(~sets, d["error"].isna())
    d = d.assign(se=d["error"] ** 2, lost=gone)
    agg = dict(mse=("se", "mean"), mean_error=("error", "mean"), lost_share=("lost", "mean"),
               measured_share=("measured", "mean"),
               negative_share=("negative_update", "mean"))
    per_kind = d.groupby(["method", "run", "kind"], observed=True).agg(**agg).reset_index()
    frames = [per_kind]
    if "all" in kinds_with_all(tables.study):
        everything = d.groupby(["method", "run"], observed=True).agg(**agg).reset_index()
        everything["kind"] = "all"
        frames.append(everything)
    out = pd.concat(frames, ignore_index=True)
    out["kind"] = pd.Categorical(out["kind"].astype(str), categories=kinds_with_all(
        tables.study), ordered=True)
    out["rmse"] = np.sqrt(out.pop("mse"))
    return out.sort_values(["method", "kind", "run"]).reset_index(drop=True)


def consistency(tables: StudyTables) -> Any:
    """Per (method, kind): how honest the tracks are, over steps 1..S of every run (for a
    multi-target tracker, over the target-steps with an assigned track).

    Columns: method, kind, n (target-steps), anees (average NEES), band_lo, band_hi (its
    95 % chi-square band for n samples of a consistent filter), high_share (share of
    target-steps with NEES above the 99 % point of chi-square(4), 13.28; a consistent filter
    has 1 %), median_nees, restarts and map_corrections (per run, mean), runs, diverged
    (runs whose largest position error exceeds :data:`DIVERGED_THRESHOLD`).
    """
    import pandas as pd

    d = tables.steps[tables.steps["step"] >= 1]
    rows = []
    for kind in kinds_with_all(tables.study):
        dk = d if kind == "all" else d[d["kind"] == kind]
        for method, g in dk.groupby("method", observed=True, sort=True):
            nees = g["nees"].to_numpy(float)
            # A multi-target tracker's target-steps without an assigned track have no NEES.
            nees = nees[~np.isnan(nees)]
            lo, hi = nees_band(nees.size)
            per_run = g.groupby("run")
            runs = per_run.ngroups
            restarts = g["restarted"].to_numpy() if "restarted" in g else np.zeros(len(g))
            mapc = g["map_corrected"].to_numpy() if "map_corrected" in g else np.zeros(len(g))
            rows.append(dict(
                method=method, kind=kind, n=nees.size,
                anees=float(nees.mean()) if nees.size else math.nan,
                band_lo=float(lo), band_hi=float(hi),
                high_share=float((nees > NEES_HIGH).mean()) if nees.size else math.nan,
                median_nees=float(np.median(nees)) if nees.size else math.nan,
                restarts=float(restarts.sum() / runs), map_corrections=float(mapc.sum() / runs),
                runs=runs, diverged=int((per_run["error"].max() > DIVERGED_THRESHOLD).sum())))
    return pd.DataFrame(rows)


def nees_over_time(tables: StudyTables) -> Any:
    """Average NEES at each step per (method, kind), with its 95 % chi-square band.

    Columns: method, kind, step, anees, band_lo, band_hi, n (runs x the kind's targets).
    """
    import pandas as pd

    st = tables.steps
    frames = []
    for kind in kinds_with_all(tables.study):
        dk = st if kind == "all" else st[st["kind"] == kind]
        g = dk.groupby(["method", "step"], observed=True)["nees"].agg(["mean", "size"])
        g = g.reset_index().rename(columns={"mean": "anees", "size": "n"})
        g["kind"] = kind
        frames.append(g)
    out = pd.concat(frames, ignore_index=True)
    out["band_lo"], out["band_hi"] = nees_band(out["n"].to_numpy())
    return out[["method", "kind", "step", "anees", "band_lo", "band_hi", "n"]]


#: Fewer runs than this make an interval unreliable: summaries flag them (``small_sample``).
SMALL_SAMPLE = 10
#: The values each run metric can take: its intervals are clipped to them (a t-interval
#: of a few runs can reach below zero, where no RMSE lies).
METRIC_RANGES: dict[str, tuple[float | None, float | None]] = {
    "rmse": (0.0, None), "mean_error": (0.0, None), "lost_share": (0.0, 1.0),
    "gospa": (0.0, None), "localisation": (0.0, None), "missed": (0.0, None),
    "false": (0.0, None),
    "measured_share": (0.0, 1.0), "negative_share": (0.0, 1.0)}


def _clip(values: Any, bounds: tuple[float | None, float | None]) -> Any:
    lo, hi = bounds
    return np.clip(np.asarray(values, dtype=float), lo, hi) if (lo, hi) != (None, None) \
        else values


def summary(metrics: Any, column: str = "rmse", level: float = LEVEL,
            bounds: tuple[float | None, float | None] | None = None) -> Any:
    """Across-run statistics of a run metric per (method, kind).

    Columns: method, kind, n (runs), mean, mean_lo, mean_hi (t-interval), median,
    median_lo, median_hi (order-statistic interval), small_sample (n <
    :data:`SMALL_SAMPLE`: the intervals rest on too few runs to be trusted).

    The interval bounds are clipped to ``bounds``, by default the metric's range in
    :data:`METRIC_RANGES` (an RMSE interval never goes below 0).
    """
    import pandas as pd

    rng = bounds if bounds is not None else METRIC_RANGES.get(column, (None, None))
    rows = []
    for (method, kind), g in metrics.groupby(["method", "kind"], observed=True, sort=True):
        x = g[column].to_numpy(float)
        mean, t_lo, t_hi = t_interval(x, level)
        med, mlo, mhi = median_interval(x, level)
        lo, hi, mlo, mhi = (float(_clip(v, rng)) for v in (t_lo, t_hi, mlo, mhi))
        rows.append(dict(method=method, kind=kind, n=x.size, mean=float(mean),
                         mean_lo=lo, mean_hi=hi, median=med, median_lo=mlo,
                         median_hi=mhi, small_sample=bool(x.size < SMALL_SAMPLE)))
    return pd.DataFrame(rows)


def references(study: Study) -> dict[str, dict[str, str | None]]:
    """The myopic and random method each method is compared with (paired differences).

    - ``random``: the first method with planner ``random``, the same tracker settings (the
      tracker decides how a random policy tracks) and the same ``steps_per_epoch``; failing
      that, any with the same tracker settings.
    - ``myopic``: the first method with planner ``pg``, ``horizon = 1`` and the same
      ``visibility``, ``objective``, tracker settings and ``steps_per_epoch``.

    A method is not compared with itself, a ``random`` method with nothing (myopic against
    random already shows that difference), and an entry is None when no method matches.
    """
    out: dict[str, dict[str, str | None]] = {}
    for m in study.methods:
        s = m.settings

        def first(pred: Callable[[RunSettings, RunSettings], bool], m: Method = m
                  ) -> str | None:
            """The first other method whose settings ``o`` satisfy ``pred(o, s)``, ``s``
            being ``m``'s settings."""
            for other in study.methods:
                if other.name != m.name and pred(other.settings, m.settings):
                    return other.name
            return None

        rnd = first(lambda o, s: o.planner == "random" and o.tracker == s.tracker
                    and o.steps_per_epoch == s.steps_per_epoch)
        if rnd is None:
            rnd = first(lambda o, s: o.planner == "random" and o.tracker == s.tracker)
        myo = first(lambda o, s: o.planner == "pg" and o.horizon == 1
                    and o.visibility == s.visibility and o.objective == s.objective
                    and o.tracker == s.tracker
                    and o.steps_per_epoch == s.steps_per_epoch)
        if s.planner == "random":
            # random vs myopic is myopic vs random with the sign flipped.
            rnd = myo = None
        if s.planner == "pg" and s.horizon == 1:
            myo = None
        out[m.name] = {"myopic": myo, "random": rnd}
    return out


def paired_differences(metrics: Any, study: Study, column: str = "rmse",
                       level: float = LEVEL,
                       pairs: Sequence[tuple[str, str]] | None = None,
                       refs: dict[str, dict[str, str | None]] | None = None) -> Any:
    """Paired differences ``method - reference`` of a run metric, per run, summarized.

    For each method, each of its :func:`references` (or each ``(method, reference)`` of
    ``pairs``, or of ``refs``: method -> {label: reference method or None}) and each kind:
    ``d_r = x(method, r) - x(reference, r)`` over the runs both finished; the mean with its
    paired t-interval, the median with its order-statistic interval, and the share of runs
    where the method is lower (better).

    Columns: method, against (``myopic`` or ``random``; ``given`` for ``pairs``; the labels
    of ``refs``), reference, kind, n, mean, mean_lo, mean_hi, median, median_lo, median_hi,
    better_share, small_sample (n < :data:`SMALL_SAMPLE`). A difference of two values in
    ``[lo, hi]`` (:data:`METRIC_RANGES`) lies in ``[lo - hi, hi - lo]``: the intervals are
    clipped to it.
    """
    import pandas as pd

    wide = metrics.pivot_table(index=["kind", "run"], columns="method", values=column,
                               observed=True)
    todo: list[tuple[str, str, str | None]]
    if pairs is not None:
        todo = [(method, "given", ref) for method, ref in pairs]
    else:
        table = references(study) if refs is None else refs
        todo = [(method, against, ref) for method, against_refs in table.items()
                for against, ref in against_refs.items()]
    rows = []
    for method, against, ref in todo:
        if ref is None or method not in wide or ref not in wide:
            continue
        for kind in kinds_with_all(study):
            if kind not in wide.index.get_level_values(0):
                continue
            both = wide.loc[kind, [method, ref]].dropna()
            d = (both[method] - both[ref]).to_numpy(float)
            mean, t_lo, t_hi = t_interval(d, level)
            lo, hi = float(t_lo), float(t_hi)
            med, mlo, mhi = median_interval(d, level)
            vlo, vhi = METRIC_RANGES.get(column, (None, None))
            if vlo is not None and vhi is not None:
                lo, hi, mlo, mhi = (float(_clip(v, (vlo - vhi, vhi - vlo)))
                                    for v in (lo, hi, mlo, mhi))
            rows.append(dict(method=method, against=against, reference=ref, kind=kind,
                             n=d.size, mean=float(mean), mean_lo=float(lo),
                             mean_hi=float(hi), median=med, median_lo=mlo,
                             median_hi=mhi,
                             better_share=float(np.mean(d < 0)) if d.size else math.nan,
                             small_sample=bool(d.size < SMALL_SAMPLE)))
    return pd.DataFrame(rows)


def rmse_over_time(tables: StudyTables, level: float = LEVEL) -> Any:
    """Position RMSE at each step per (method, kind) with a band across runs.

    At step t, with ``m_r(t)`` run r's mean over the kind's targets of error^2, the RMSE is
    ``sqrt(mean_r m_r(t))`` and the band is ``sqrt`` of the t-interval of that mean
    (clipped at 0): a 95 % interval for the RMSE of the step across runs.

    Columns: method, kind, step, rmse, lo, hi, n.
    """
    import pandas as pd

    st = tables.steps
    se = st.assign(se=st["error"] ** 2)
    frames = [se.groupby(["method", "kind", "step", "run"], observed=True)["se"].mean()
              .reset_index()]
    if "all" in kinds_with_all(tables.study):
        a = se.groupby(["method", "step", "run"], observed=True)["se"].mean().reset_index()
        a["kind"] = "all"
        frames.append(a)
    per_run = pd.concat(frames, ignore_index=True)
    per_run["kind"] = per_run["kind"].astype(str)
    rows = []
    for (method, kind), g in per_run.groupby(["method", "kind"], observed=True, sort=False):
        wide = g.pivot(index="run", columns="step", values="se")       # (runs, steps)
        mean, lo, hi = t_interval(wide.to_numpy(float), level, axis=0)
        rows.append(pd.DataFrame(dict(
            method=method, kind=kind, step=wide.columns.to_numpy(), rmse=np.sqrt(mean),
            lo=np.sqrt(np.clip(lo, 0.0, None)), hi=np.sqrt(np.clip(hi, 0.0, None)),
            n=wide.notna().sum(axis=0).to_numpy())))
    out = pd.concat(rows, ignore_index=True)
    out["method"] = out["method"].astype(tables.steps["method"].dtype)
    return out.sort_values(["method", "kind", "step"]).reset_index(drop=True)


def planning_summary(tables: StudyTables) -> Any:
    """Per method: decisions, planning time per decision (ms: mean, median, 90th
    percentile, max), total planning time per run (s), converged share and sweeps (mean,
    max) where the planner reports them, and the mean potential Phi (nats)."""
    import pandas as pd

    rows = []
    dec = tables.decisions
    for method, g in dec.groupby("method", observed=True, sort=True):
        ms = 1e3 * g["planning_seconds"].to_numpy(float)
        conv = g["converged"].dropna().astype(float).to_numpy()
        sweeps = g["sweeps"].dropna().astype(float).to_numpy()
        per_run = g.groupby("run")["planning_seconds"].sum().to_numpy(float)
        rows.append(dict(
            method=method, decisions=len(g), mean_ms=float(ms.mean()),
            median_ms=float(np.median(ms)), p90_ms=float(np.percentile(ms, 90)),
            max_ms=float(ms.max()), seconds_per_run=float(per_run.mean()),
            converged_share=float(conv.mean()) if conv.size else math.nan,
            sweeps_mean=float(sweeps.mean()) if sweeps.size else math.nan,
            sweeps_max=float(sweeps.max()) if sweeps.size else math.nan,
            phi_mean=float(g["phi"].mean())))
    return pd.DataFrame(rows)


def sensing_summary(tables: StudyTables) -> Any:
    """Per method, over sensor-steps 1..S: looks (share of sensor-steps pointed at a
    target), measurements per sensor-step, and the share of looks that missed."""
    import pandas as pd

    s = tables.sensors[tables.sensors["step"] >= 1]
    rows = []
    for method, g in s.groupby("method", observed=True, sort=True):
        looks = g["target"].to_numpy() >= 0
        rows.append(dict(method=method, look_share=float(looks.mean()),
                         measurements_per_sensor_step=float(g["measured"].mean()),
                         miss_share=float(g["missed"].to_numpy()[looks].mean())
                         if looks.any() else math.nan))
    return pd.DataFrame(rows)


def horizon_groups(study: Study, minimum: int = 3) -> list[list[Method]]:
    """Groups of methods that differ only in the horizon K (at least ``minimum`` distinct K),
    each sorted by K: the report plots RMSE and planning time against K for them.

    A K = 1 method joins the groups of either execution (OL and OLF are the same policy
    when K = 1).
    """
    groups: dict[str, list[Method]] = {}
    for m in study.methods:
        d = m.to_dict()
        for k in ("name", "horizon", "execution"):
            d.pop(k)
        groups.setdefault(json.dumps(d, sort_keys=True, default=str), []).append(m)
    out = []
    for members in groups.values():
        myopic = [m for m in members if m.settings.horizon == 1]
        executions = dict.fromkeys(m.settings.execution for m in members
                                   if m.settings.horizon > 1)
        for execution in executions:
            by_k: dict[int, Method] = {}
            for m in myopic + [m for m in members if m.settings.horizon > 1
                               and m.settings.execution == execution]:
                by_k.setdefault(m.settings.horizon, m)
            if len(by_k) >= minimum:
                out.append([by_k[k] for k in sorted(by_k)])
    return out



def gospa_summary(tables: StudyTables, level: float = LEVEL) -> Any:
    """GOSPA per method: each run's mean over steps 1..S, summarised across runs (mean with
    its t-interval, median with its order-statistic interval), and each part's mean.

    Columns: method, n, mean, lo, hi, median, median_lo, median_hi, localisation, missed,
    false (mean share of GOSPA^2 over steps, m^2), false_tracks (mean per step).
    """
    import pandas as pd

    g = tables.gospa
    per_run = g.groupby(["method", "run"], observed=True).agg(
        gospa=("gospa", "mean"), localisation=("localisation", "mean"),
        missed=("missed", "mean"), false=("false", "mean"),
        false_tracks=("false_tracks", "mean")).reset_index()
    rows = []
    for method, r in per_run.groupby("method", observed=True, sort=False):
        values = r["gospa"].to_numpy(float)
        mean, lo, hi = t_interval(values, level)
        med, mlo, mhi = median_interval(values, level)
        rows.append(dict(method=method, n=len(values), mean=mean, lo=lo, hi=hi, median=med,
                         median_lo=mlo, median_hi=mhi,
                         localisation=float(r["localisation"].mean()),
                         missed=float(r["missed"].mean()), false=float(r["false"].mean()),
                         false_tracks=float(r["false_tracks"].mean())))
    out = pd.DataFrame(rows)
    out["method"] = out["method"].astype(g["method"].dtype)
    return out.sort_values("method").reset_index(drop=True)


def gospa_over_time(tables: StudyTables, level: float = LEVEL) -> Any:
    """Mean GOSPA at each step per method with its t-interval across runs.

    Columns: method, step, gospa, lo, hi, n.
    """
    import pandas as pd

    rows = []
    for method, g in tables.gospa.groupby("method", observed=True, sort=False):
        wide = g.pivot(index="run", columns="step", values="gospa")
        mean, lo, hi = t_interval(wide.to_numpy(float), level, axis=0)
        rows.append(pd.DataFrame(dict(method=method, step=wide.columns.to_numpy(), gospa=mean,
                                      lo=np.clip(lo, 0.0, None), hi=hi,
                                      n=wide.notna().sum(axis=0).to_numpy())))
    out = pd.concat(rows, ignore_index=True)
    out["method"] = out["method"].astype(tables.gospa["method"].dtype)
    return out.sort_values(["method", "step"]).reset_index(drop=True)


def gospa_run_metrics(tables: StudyTables) -> Any:
    """Per (method, run): the means over steps 1..S of GOSPA (m) and of its localisation,
    missed and false parts (m^2), shaped like :func:`run_metrics` (kind: the one that
    covers every target, ``all`` or the scenario's only kind) so that :func:`summary` and
    :func:`paired_differences` take it.

    Columns: method, run, kind, gospa, localisation, missed, false.
    """
    import pandas as pd

    per_run = tables.gospa.groupby(["method", "run"], observed=True).agg(
        gospa=("gospa", "mean"), localisation=("localisation", "mean"),
        missed=("missed", "mean"), false=("false", "mean")).reset_index()
    kinds = kinds_with_all(tables.study)
    per_run["kind"] = pd.Categorical([kinds[-1]] * len(per_run), categories=kinds,
                                     ordered=True)
    cols = ["method", "run", "kind", "gospa", "localisation", "missed", "false"]
    return per_run[cols].sort_values(["method", "run"]).reset_index(drop=True)
