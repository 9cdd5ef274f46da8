"""Benchmark: sensorplan planners against Stone Soup's sensor managers (docs/benchmarks.md).

Both parts run in one process on the same scenario: the paper's world (600 m map, 17 moves of
20/40 m, radars at 490/500/510 m, M = 5 targets), Stone Soup's own tracking types, our radar
as a Stone Soup sensor (``sensorplan.integrations.stonesoup``).

Stone Soup's managers run with two rewards:
:class:`~sensorplan.integrations.stonesoup.MutualInformationReward` (the bridge's; Stone
Soup's predictor and updater on our measurement model; the same objective as ours) and
Stone Soup's own ``ExpectedKLDivergence`` (methods marked EKL; another objective: it counts
every track in a radar's field of view and scores KL(prediction || update), see
docs/stonesoup.md).

**One decision** (K = 1, e = 1, ``visibility = "mean"``), N = 1, 2, 3 platforms, several
random instances: Stone Soup's ``BruteForceSensorManager`` and ``GreedySensorManager`` with
either reward against our ``brute-force`` and
``pg`` behind :class:`~sensorplan.integrations.stonesoup.SensorplanManager`. Measured: wall
and CPU time of ``choose_actions`` and the chosen joint action's information, evaluated by one
evaluator, :func:`sensorplan.planners.information.potential`, on the equivalent plan (the mapping
config -> plan is exact: the reward of a config equals that potential, which the run checks).
Stone Soup's time is always also extrapolated from a fixed, seeded uniform sample of its reward
calls: manager overhead (the same enumeration with a zero reward, measured in full) plus joint
actions times the mean reward call. It runs in full when that estimate is at most
``--max-ss-seconds``, for N = 3 (85^3 = 614,125 joint actions) only on the first
``--full-n3`` instances; elsewhere the extrapolation is reported (and N = 1, 2 and the full
N = 3 runs check it). Instances are the first seeds (from 1000) where a look can be visible.

**Closed loop**, ``--seeds`` runs of ``--steps`` steps (paper scenario, common random numbers
per seed: the same truth, initial estimates and measurement noise for every method; Stone
Soup EKF tracks; a missed look changes nothing, as in Stone Soup): Stone Soup greedy and MCTS
(``MonteCarloTreeSearchSensorManager``, its defaults: 100 iterations) with either reward,
against ``pg`` with K = 1 and K = 3 (OLF, decide every step; our default probabilistic
visibility) and ``pg`` K = 1 with ``visibility = "mean"`` (the objective Stone Soup's reward
computes). Reported: position RMSE (mean over runs with a 95 % t-interval, median, share of
target-steps with error > 50 m), by target kind, and planning time per decision (wall and
CPU). Stone Soup's MCTS draws from NumPy's global generator, so each run seeds it.

Run::

    .venv/bin/python benchmarks/vs_stonesoup.py [--part all|decision|closed] [--instances 3]
        [--seeds 10] [--steps 50] [--sample 1000] [--out out/vs_stonesoup]
        [--figures docs/figures] [--closed-methods NAME,NAME,...]

Other processes share the machine's 2 cores: CPU time (``time.process_time``) is reported
next to wall time.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats
from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                ConstantVelocity)
from stonesoup.platform import FixedPlatform
from stonesoup.predictor.kalman import ExtendedKalmanPredictor
from stonesoup.sensormanager import BruteForceSensorManager, GreedySensorManager
from stonesoup.sensormanager.reward import ExpectedKLDivergence
from stonesoup.sensormanager.tree_search import MonteCarloTreeSearchSensorManager
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import State
from stonesoup.updater.kalman import ExtendedKalmanUpdater

import sensorplan
from sensorplan.planners.information import potential
from sensorplan.integrations.stonesoup import (LatticeMovable, LatticeMoveAction,
                                               MutualInformationReward, SensorplanManager,
                                               SensorplanRadar, execute, from_tracks,
                                               set_aim_candidates, to_ground_truth_state,
                                               to_tracks)
from sensorplan.planners.problem import Plan, PlanningProblem
from sensorplan.simulation.scenario import draw_initial, make_truth, paper_scenario
from sensorplan.models.sensors import SensorParams
from sensorplan.simulation import run_streams

T0 = datetime.datetime(2024, 1, 1)
STEP = datetime.timedelta(seconds=1)
ALTITUDES = (490.0, 500.0, 510.0)
Q = 0.05
P0 = np.diag([400.0, 400.0, 4.0, 4.0])
LOST = 50.0


# ------------------------------------------------------------------------------ helpers


def timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``fn()``, its wall time and its CPU time (s)."""
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def make_platforms(positions: np.ndarray, headings: np.ndarray) -> list[FixedPlatform]:
    """Stone Soup platforms with our move lattice and radar (paper parameters)."""
    out = []
    for (x, y), h, z in zip(positions, headings, ALTITUDES):
        radar = SensorplanRadar(params=SensorParams(altitude=z), heading=float(h))
        ctl = LatticeMovable(states=[State([[float(x)], [float(y)], [z]], timestamp=T0)],
                             position_mapping=(0, 1, 2))
        out.append(FixedPlatform(movement_controller=ctl, sensors=[radar]))
    return out


def stonesoup_filter() -> tuple[ExtendedKalmanPredictor, ExtendedKalmanUpdater]:
    """Stone Soup's EKF with the CWNA motion model of docs/model.md."""
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q),
                                                        ConstantVelocity(Q)])
    return ExtendedKalmanPredictor(transition), ExtendedKalmanUpdater(None, use_joseph_cov=True)


def mi_reward(return_tracks: bool = False) -> MutualInformationReward:
    predictor, updater = stonesoup_filter()
    return MutualInformationReward(predictor=predictor, updater=updater,
                                   return_tracks=return_tracks)


def ekl_reward(return_tracks: bool = False) -> ExpectedKLDivergence:
    """Stone Soup's own information reward, as a Stone Soup user sets it up: with Gaussian
    tracks, KL(prediction || update) of every track whose predicted mean is in a radar's
    field of view, at a noise-free measurement there (docs/stonesoup.md)."""
    predictor, updater = stonesoup_filter()
    return ExpectedKLDivergence(predictor=predictor, updater=updater,
                                return_tracks=return_tracks)


#: The Stone Soup rewards by the name used in method names.
REWARDS: dict[str, Callable[..., Any]] = {"MI": mi_reward, "EKL": ekl_reward}


def config_plan(config: dict, platforms: list, tracks: list) -> Plan:
    """The plan (K = 1) equivalent to a Stone Soup configuration."""
    positions, targets = [], []
    for p in platforms:
        (m,) = config[p]
        assert isinstance(m, LatticeMoveAction)
        (aim,) = config[p.sensors[0]]
        positions.append(np.ravel(m.target_value)[:2])
        targets.append(next(k for k, t in enumerate(tracks) if t is aim.target))
    return Plan(np.array(positions)[:, None], np.array(targets)[:, None])


def ci95(x: np.ndarray) -> tuple[float, float, float]:
    """Mean and the 95 % t-interval of the mean."""
    x = np.asarray(x, dtype=float)
    m = float(x.mean())
    if len(x) < 2:
        return m, math.nan, math.nan
    h = float(stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))
    return m, m - h, m + h


# --------------------------------------------------------------------------- one decision


def decision_instance(seed: int) -> tuple[np.ndarray, ...]:
    """Means, covariances, platform positions and headings of one decision (paper-like;
    platforms 40 m from every edge so all 17 moves stay inside the map)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(100.0, 500.0, size=(5, 2))
    speed = rng.uniform(3.0, 6.0, size=5)
    course = rng.uniform(-math.pi, math.pi, size=5)
    means = np.column_stack([xy, speed * np.cos(course), speed * np.sin(course)])
    covs = np.broadcast_to(P0, (5, 4, 4)).copy()
    positions = rng.uniform(40.0, 560.0, size=(3, 2))
    headings = rng.uniform(-math.pi, math.pi, size=3)
    return means, covs, positions, headings


def nearest_aim(radar: SensorplanRadar) -> tuple[Any, tuple[float, float]]:
    """The aim candidate with the smallest angle off the radar's heading."""
    xy = radar.ground_position
    off = [abs(math.remainder(math.atan2(p[1] - xy[1], p[0] - xy[0]) - radar.heading,
                              2 * math.pi)) for _, p in radar.aim_candidates]
    return radar.aim_candidates[int(np.argmin(off))]


def informative_seeds(count: int) -> list[int]:
    """The first ``count`` instance seeds (from 1000 on) where one platform alone can make
    a visible look (``mean`` visibility): the others' optimum is zero information, and every
    method ties."""
    from sensorplan.planners import make_planner

    seeds, seed = [], 1000
    while len(seeds) < count:
        means, covs, positions, headings = decision_instance(seed)
        problem = PlanningProblem(means=means, covs=covs, positions=positions[:1],
                                  headings=headings[:1], sensors=(SensorParams(altitude=490.0),),
                                  horizon=1, visibility="mean")
        if make_planner("brute-force").plan(problem).potential > 0:
            seeds.append(seed)
        seed += 1
    return seeds


def stonesoup_brute_force(platforms: list, tracks: list, t1: datetime.datetime,
                          sample: int, max_seconds: float, seed: int,
                          allow_full: bool, make_reward: Callable[[], Any] = mi_reward
                          ) -> dict[str, Any]:
    """Time Stone Soup's brute force with the reward ``make_reward()``: in full if
    affordable, else extrapolated."""
    reward = make_reward()
    actionables = platforms + [p.sensors[0] for p in platforms]
    choices = [list(next(iter(a.actions(t1)))) for a in actionables]
    n_joint = math.prod(len(c) for c in choices)
    # Manager overhead: the same enumeration with a zero reward, in full.
    null = BruteForceSensorManager(platforms=set(platforms),
                                   reward_function=lambda config, tracks, t: 0.0)
    _, ov_wall, ov_cpu = timed(lambda: null.choose_actions(tracks, t1))
    # A fixed, seeded uniform sample of joint actions; time the reward calls.
    rng = np.random.default_rng(seed)
    configs = [{a: (c[rng.integers(len(c))],) for a, c in zip(actionables, choices)}
               for _ in range(sample)]
    _, s_wall, s_cpu = timed(lambda: [reward(cfg, tracks, t1) for cfg in configs])
    est_wall = ov_wall + n_joint * s_wall / sample
    est_cpu = ov_cpu + n_joint * s_cpu / sample
    out = {"joint_actions": n_joint, "sample": sample, "overhead_wall": ov_wall,
           "reward_call_ms": 1e3 * s_wall / sample, "reward_call_cpu_ms": 1e3 * s_cpu / sample,
           "estimated_wall": est_wall, "estimated_cpu": est_cpu, "full_run": False}
    if allow_full and est_wall <= max_seconds:
        mgr = BruteForceSensorManager(platforms=set(platforms), reward_function=reward)
        (configs_out,), wall, cpu = timed(lambda: mgr.choose_actions(tracks, t1))
        out.update(full_run=True, wall=wall, cpu=cpu, config=configs_out)
    else:
        out.update(wall=est_wall, cpu=est_cpu, config=None)
    return out


def one_decision(args: argparse.Namespace) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    t1 = T0 + STEP
    warm = None
    for inst, seed in enumerate(informative_seeds(args.instances)):
        means, covs, positions, headings = decision_instance(seed)
        for N in (1, 2, 3):
            platforms = make_platforms(positions[:N], headings[:N])
            radars = [p.sensors[0] for p in platforms]
            tracks = to_tracks(means, covs, T0)
            set_aim_candidates(radars, tracks, 1.0)
            for radar in radars:
                # The radar was looking at the track nearest its boresight: Stone Soup's
                # greedy evaluates a platform's moves with the radar's current aim.
                radar.aim_target, radar.aim = nearest_aim(radar)
            problem = PlanningProblem(means=means, covs=covs, positions=positions[:N],
                                      headings=headings[:N],
                                      sensors=tuple(r.params for r in radars), horizon=1,
                                      visibility="mean")
            reward = mi_reward()

            def record(method: str, config: dict | None, wall: float, cpu: float,
                       **extra: Any) -> None:
                row = {"instance": inst, "seed": seed, "N": N, "method": method, "wall": wall,
                       "cpu": cpu, **extra}
                if config is not None:
                    plan = config_plan(config, platforms, tracks)
                    phi, _ = potential(problem, plan)
                    row.update(information=phi,
                               stonesoup_reward=float(reward(config, tracks, t1)),
                               positions=plan.positions[:, 0].tolist(),
                               targets=plan.targets[:, 0].tolist())
                else:
                    row["information"] = None
                rows.append(row)
                info = "n/a" if row["information"] is None else f"{row['information']:.4f}"
                print(f"  inst {inst} N={N} {method:22s} wall {wall:10.4f} s  cpu {cpu:10.4f} s"
                      f"  information {info}", flush=True)

            for planner in ("brute-force", "pg"):
                mgr = SensorplanManager(platforms=platforms, planner=planner, horizon=1,
                                        visibility="mean", rng=0)
                if warm is None:                     # compile the numba kernels once
                    warm = mgr.choose_actions(tracks, t1)
                runs = [timed(lambda: mgr.choose_actions(tracks, t1)) for _ in range(5)]
                (cfg,), _, _ = runs[0]
                record(f"sensorplan {planner}", cfg, float(np.median([r[1] for r in runs])),
                       float(np.median([r[2] for r in runs])))
            for tag, make_reward in REWARDS.items():
                suffix = "" if tag == "MI" else f" ({tag})"
                greedy = GreedySensorManager(platforms=set(platforms),
                                             reward_function=make_reward())
                (cfg,), wall, cpu = timed(lambda: greedy.choose_actions(tracks, t1))
                record("stonesoup greedy" + suffix, cfg, wall, cpu)
                bf = stonesoup_brute_force(platforms, tracks, t1, args.sample,
                                           args.max_ss_seconds, seed=inst,
                                           allow_full=N < 3 or inst < args.full_n3,
                                           make_reward=make_reward)
                cfg = bf.pop("config")
                record("stonesoup brute force" + suffix, cfg, bf.pop("wall"), bf.pop("cpu"),
                       **bf)
    return rows


# ----------------------------------------------------------------------------- closed loop


@dataclass
class Method:
    name: str
    kind: str                 # "pg", "ss-greedy", "ss-mcts"
    horizon: int = 1
    visibility: str = "probabilistic"
    reward: str = "MI"        # Stone Soup's managers: a key of REWARDS


CLOSED_METHODS = (Method("stonesoup greedy", "ss-greedy"),
                  Method("stonesoup MCTS", "ss-mcts"),
                  Method("stonesoup greedy (EKL)", "ss-greedy", reward="EKL"),
                  Method("stonesoup MCTS (EKL)", "ss-mcts", reward="EKL"),
                  Method("sensorplan pg K=1", "pg", 1),
                  Method("sensorplan pg K=3", "pg", 3),
                  Method("sensorplan pg K=1 (mean)", "pg", 1, "mean"))


def closed_loop_run(method: Method, seed: int, steps: int) -> dict[str, Any]:
    """One paired run (the streams of ``sensorplan.simulation.run_streams(seed)``)."""
    scenario = paper_scenario()        # tracked with miss_update "none" (plain EKF)
    streams = run_streams(seed)
    truth_rng = np.random.default_rng(streams["truth"])
    init = draw_initial(scenario, truth_rng, np.random.default_rng(streams["init"]))
    truth = make_truth(scenario, init.truth, truth_rng)
    N = len(scenario.sensors)
    noise = np.stack([np.random.default_rng(c).standard_normal((steps, 2))
                      for c in streams["noise"].spawn(N)], axis=1)
    platforms = make_platforms(init.positions, init.headings)
    radars = [p.sensors[0] for p in platforms]
    tracks = to_tracks(init.estimate, P0, T0)
    predictor, updater = stonesoup_filter()
    if method.kind == "pg":
        manager: Any = SensorplanManager(platforms=platforms, planner="pg",
                                         horizon=method.horizon, visibility=method.visibility,
                                         rng=np.random.default_rng(streams["planner"]))
    elif method.kind == "ss-greedy":
        manager = GreedySensorManager(platforms=set(platforms),
                                      reward_function=REWARDS[method.reward]())
    else:
        np.random.seed(seed)          # Stone Soup's MCTS draws from NumPy's global generator
        manager = MonteCarloTreeSearchSensorManager(
            platforms=set(platforms), reward_function=REWARDS[method.reward](True))
    errors = np.empty((steps, len(tracks)))
    walls, cpus = [], []
    for t in range(1, steps + 1):
        now = T0 + t * STEP

        def decide() -> dict:
            if method.kind != "pg":
                set_aim_candidates(radars, tracks, 1.0)
            return manager.choose_actions(tracks, now)[0]

        config, wall, cpu = timed(decide)
        walls.append(wall)
        cpus.append(cpu)
        execute(config, now)
        x_true = truth.step()
        for track in tracks:
            track.append(predictor.predict(track.state, timestamp=now))
        for i, radar in enumerate(radars):
            target = next(tr for tr in tracks if tr.id == radar.aim_target.id)
            gt = to_ground_truth_state(x_true[tracks.index(target)], now)
            model = radar.measurement_model
            for det in radar.measure([gt], noise=model.scaled_noise(gt, noise[t - 1, i])):
                target.append(updater.update(SingleHypothesis(target.state, det)))
        est, _ = from_tracks(tracks)
        errors[t - 1] = np.hypot(*(x_true[:, :2] - est[:, :2]).T)
    return {"errors": errors, "wall": walls, "cpu": cpus}


def closed_loop(args: argparse.Namespace) -> dict[str, Any]:
    kinds = np.array(paper_scenario().target_kinds)
    out: dict[str, Any] = {"target_kinds": kinds.tolist(), "methods": {}}
    chosen = args.closed_methods.split(",") if args.closed_methods else None
    unknown = sorted(set(chosen or ()) - {m.name for m in CLOSED_METHODS})
    if unknown:
        raise SystemExit(f"--closed-methods: unknown {unknown}; choose from "
                         f"{[m.name for m in CLOSED_METHODS]}")
    for method in CLOSED_METHODS:
        if chosen is not None and method.name not in chosen:
            continue
        runs = []
        for seed in range(args.seeds):
            run, wall, _ = timed(lambda: closed_loop_run(method, seed, args.steps))
            runs.append(run)
            print(f"  {method.name:26s} seed {seed}: RMSE "
                  f"{math.sqrt(float(np.mean(run['errors'] ** 2))):7.2f} m  ({wall:.1f} s)",
                  flush=True)
        errors = np.stack([r["errors"] for r in runs])                   # (runs, S, M)
        rmse = np.sqrt(np.mean(errors**2, axis=(1, 2)))
        by_kind = {k: np.sqrt(np.mean(errors[:, :, kinds == k] ** 2, axis=(1, 2)))
                   for k in ("cv", "dubins")}
        walls = np.concatenate([r["wall"] for r in runs])
        cpus = np.concatenate([r["cpu"] for r in runs])
        out["methods"][method.name] = {
            "rmse_runs": rmse.tolist(), "rmse": ci95(rmse), "rmse_median": float(np.median(rmse)),
            "rmse_by_kind": {k: ci95(v) for k, v in by_kind.items()},
            "lost_share": float(np.mean(errors > LOST)),
            "rmse_per_step": np.sqrt(np.mean(errors**2, axis=(0, 2))).tolist(),
            "plan_wall_ms": 1e3 * float(walls.mean()), "plan_cpu_ms": 1e3 * float(cpus.mean()),
            "plan_wall_ms_median": 1e3 * float(np.median(walls))}
    return out


# -------------------------------------------------------------------------------- report


def report(decision: list[dict[str, Any]] | None, closed: dict[str, Any] | None,
           figures: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figures.mkdir(parents=True, exist_ok=True)
    if decision:
        methods = [m for m in ("stonesoup brute force", "stonesoup greedy",
                               "stonesoup brute force (EKL)", "stonesoup greedy (EKL)",
                               "sensorplan brute-force", "sensorplan pg")
                   if any(r["method"] == m for r in decision)]
        print("\nOne decision (median over instances; information relative to the optimum):")
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
        for m in methods:
            Ns, t_med, c_med, rel, extrapolated = [], [], [], [], []
            for N in (1, 2, 3):
                rows = [r for r in decision if r["method"] == m and r["N"] == N]
                best = {r["instance"]: r["information"] for r in decision
                        if r["method"] == "sensorplan brute-force" and r["N"] == N}
                walls = [r["wall"] for r in rows]
                cpus = [r["cpu"] for r in rows]
                ratios = [r["information"] / best[r["instance"]] for r in rows
                          if r["information"] is not None and best[r["instance"]] > 0]
                est = "" if all(r.get("full_run", True) for r in rows) else " (extrapolated)"
                print(f"  N={N} {m:24s} wall {np.median(walls):11.4f} s  cpu "
                      f"{np.median(cpus):11.4f} s{est}  info/opt "
                      f"{'n/a' if not ratios else f'{np.mean(ratios):.4f}'}")
                Ns.append(N)
                t_med.append(np.median(walls))
                c_med.append(np.median(cpus))
                rel.append(np.mean(ratios) if ratios else np.nan)
                extrapolated.append(bool(est))
            (line,) = ax1.plot(Ns, t_med, "o-", label=m)
            ax1.plot(Ns, c_med, ":", color=line.get_color())
            for n, t, x in zip(Ns, t_med, extrapolated):
                if x:
                    ax1.plot([n], [t], "o", ms=11, mfc="white", color=line.get_color())
                    ax1.annotate("extrapolated", (n, t), textcoords="offset points",
                                 xytext=(-78, -14), fontsize=8)
            ax2.plot(Ns, rel, "o-", label=m)
        ax1.set(yscale="log", xlabel="platforms N",
                ylabel="time per decision (s): wall solid, CPU dotted",
                xticks=[1, 2, 3], title="one decision (17 moves x 5 targets per platform)")
        ax1.legend(fontsize=8)
        ax2.set(xlabel="platforms N", ylabel="information / optimum", xticks=[1, 2, 3],
                title="chosen joint action, evaluated by sensorplan.potential")
        for N in (1, 2, 3):
            by = {(r["method"], r["instance"]): r for r in decision if r["N"] == N}
            insts = sorted({r["instance"] for r in decision})
            ss_bf = [by["stonesoup brute force", i] for i in insts]
            our_bf = [by["sensorplan brute-force", i] for i in insts]
            ratio = [a["wall"] / b["wall"] for a, b in zip(ss_bf, our_bf)]
            ratio_cpu = [a["cpu"] / b["cpu"] for a, b in zip(ss_bf, our_bf)]
            pg_vs_greedy = [by["sensorplan pg", i]["information"]
                            - by["stonesoup greedy", i]["information"] for i in insts]
            checks = [(by["stonesoup brute force", i]["estimated_cpu"],
                       by["stonesoup brute force", i]["cpu"]) for i in insts
                      if by["stonesoup brute force", i]["full_run"]]
            print(f"  N={N}: Stone Soup brute force / ours: wall x{np.median(ratio):,.0f} "
                  f"(min x{min(ratio):,.0f}), cpu x{np.median(ratio_cpu):,.0f}; pg - SS greedy "
                  f"information: min {min(pg_vs_greedy):+.4f}, mean "
                  f"{np.mean(pg_vs_greedy):+.4f} nats; extrapolation check (estimated vs "
                  f"measured CPU s): {[(round(a, 2), round(b, 2)) for a, b in checks]}")
        gaps = [abs(r["stonesoup_reward"] - r["information"]) for r in decision
                if r["information"] is not None]
        print(f"  largest |Stone Soup reward - potential| of a chosen action: {max(gaps):.2e}")
        fig.tight_layout()
        fig.savefig(figures / "stonesoup_decision.png", dpi=110)
        plt.close(fig)
    if closed:
        print("\nClosed loop (position RMSE over runs, m; planning time per decision):")
        names = list(closed["methods"])
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
        for k, name in enumerate(names):
            r = closed["methods"][name]
            m, lo, hi = r["rmse"]
            print(f"  {name:26s} RMSE {m:7.2f} [{lo:6.2f}, {hi:6.2f}]  median "
                  f"{r['rmse_median']:6.2f}  cv {r['rmse_by_kind']['cv'][0]:6.2f}  dubins "
                  f"{r['rmse_by_kind']['dubins'][0]:6.2f}  lost {100 * r['lost_share']:5.1f} %"
                  f"  plan {r['plan_wall_ms']:8.1f} ms wall  {r['plan_cpu_ms']:8.1f} ms cpu")
            ax1.errorbar([k], [m], yerr=[[m - lo], [hi - m]], fmt="o", capsize=4)
            ax2.plot(r["rmse_per_step"], label=name)
        runs = {n: np.array(closed["methods"][n]["rmse_runs"]) for n in names}
        for ours in ("sensorplan pg K=1", "sensorplan pg K=3"):
            for theirs in ("stonesoup greedy", "stonesoup MCTS", "stonesoup greedy (EKL)",
                           "stonesoup MCTS (EKL)"):
                if ours in runs and theirs in runs:
                    d, lo, hi = ci95(runs[ours] - runs[theirs])
                    wins = int(np.sum(runs[ours] < runs[theirs]))
                    print(f"  paired RMSE difference {ours} - {theirs}: {d:+7.2f} m "
                          f"[{lo:+.2f}, {hi:+.2f}], lower in {wins}/{len(runs[ours])} runs")
        ax1.set_xticks(range(len(names)), names, rotation=25, ha="right", fontsize=8)
        ax1.set(ylabel="position RMSE (m), mean and 95 % CI over runs",
                title="closed loop, paired runs")
        ax2.set(xlabel="step", ylabel="RMSE over runs and targets (m)", yscale="log")
        ax2.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(figures / "stonesoup_closed_loop.png", dpi=110)
        plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--part", choices=("all", "decision", "closed"), default="all")
    parser.add_argument("--instances", type=int, default=3)
    parser.add_argument("--sample", type=int, default=1000)
    parser.add_argument("--max-ss-seconds", type=float, default=600.0,
                        help="run Stone Soup's brute force in full only below this estimate")
    parser.add_argument("--full-n3", type=int, default=1,
                        help="instances whose N = 3 Stone Soup brute force may run in full")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--closed-methods", default="",
                        help="comma-separated names of the closed-loop methods to run "
                             "(default: all)")
    parser.add_argument("--out", default="out/vs_stonesoup")
    parser.add_argument("--figures", default="docs/figures")
    parser.add_argument("--report-only", action="store_true",
                        help="print the tables and redraw the figures from --out's JSON")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if args.report_only:
        load = lambda name: (json.loads((out / name).read_text())  # noqa: E731
                             if (out / name).exists() else None)
        report(load("decision.json"), load("closed_loop.json"), Path(args.figures))
        return
    out.mkdir(parents=True, exist_ok=True)
    import stonesoup

    meta = {"command": " ".join([Path(sys.executable).name] + sys.argv),
            "stonesoup": stonesoup.__version__, "numpy": np.__version__,
            "sensorplan": sensorplan.__version__, "cpus": os.cpu_count(),
            "load_average_start": os.getloadavg()}
    print(json.dumps(meta), flush=True)
    decision = closed = None
    start = time.perf_counter()
    if args.part in ("all", "decision"):
        print("One decision:", flush=True)
        decision = one_decision(args)
        (out / "decision.json").write_text(json.dumps(decision, indent=1))
    if args.part in ("all", "closed"):
        print("Closed loop:", flush=True)
        closed = closed_loop(args)
        (out / "closed_loop.json").write_text(json.dumps(closed, indent=1))
    meta.update(seconds=time.perf_counter() - start, load_average_end=os.getloadavg())
    (out / "meta.json").write_text(json.dumps(meta, indent=1))
    report(decision, closed, Path(args.figures))


if __name__ == "__main__":
    main()
