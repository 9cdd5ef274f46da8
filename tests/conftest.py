"""Shared fixtures and factories for small random planning problems.

``make_problem`` and ``random_plan`` are plain functions so that hypothesis tests can call
them without function-scoped fixtures; the session-scoped fixtures ``problem_factory`` and
``plan_factory`` hand them to tests that prefer fixtures::

    def test_something(rng, problem_factory, plan_factory):
        problem = problem_factory(rng, n_sensors=2, n_targets=3, horizon=2)
        plan = plan_factory(problem, rng, p_unassigned=0.2)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from sensorplan.problem import MapRect, Plan, PlanningProblem, move_vectors
from sensorplan.sensors import SensorParams


@pytest.fixture
def rng() -> np.random.Generator:
    """The suite's seeded generator (a fresh one per test)."""
    return np.random.default_rng(12345)


def random_covariance(rng: np.random.Generator, pos_sd: tuple[float, float] = (5.0, 30.0),
                      vel_sd: tuple[float, float] = (0.5, 3.0)) -> np.ndarray:
    """A random SPD ``(4, 4)`` state covariance with correlated entries.

    Standard deviations are drawn uniformly from ``pos_sd`` (m) and ``vel_sd`` (m/s);
    correlations come from a random correlation matrix kept well conditioned.
    """
    sd = np.concatenate([rng.uniform(*pos_sd, size=2), rng.uniform(*vel_sd, size=2)])
    A = rng.normal(size=(4, 4))
    S = A @ A.T + 4.0 * np.eye(4)
    d = np.sqrt(np.diag(S))
    corr = S / np.outer(d, d)
    P = corr * np.outer(sd, sd)
    return 0.5 * (P + P.T)


def make_problem(rng: np.random.Generator, n_sensors: int = 2, n_targets: int = 2,
                 horizon: int = 2, steps_per_epoch: int = 1,
                 visibility: str = "probabilistic", objective: str = "terminal", *,
                 moves: tuple[float, ...] = (20.0, 40.0), vary_sensors: bool = False,
                 world: MapRect | None = None, dt: float = 1.0, process_noise: float = 0.05,
                 pos_sd: tuple[float, float] = (5.0, 30.0),
                 vel_sd: tuple[float, float] = (0.5, 3.0), speed: float = 3.0,
                 covs: np.ndarray | None = None,
                 sensor_kwargs: dict[str, Any] | None = None) -> PlanningProblem:
    """A small random :class:`PlanningProblem` where many looks are visible.

    Targets are spread over the middle of the map; sensor ``i`` is placed at a ground range
    drawn from [290, 410] m (inside the default 250-450 m band) from target ``i % M`` and
    heads toward it within +-0.3 rad, so that with the default field of view its looks,
    and often the others', are visible.

    Parameters
    ----------
    rng : Generator
    n_sensors, n_targets, horizon, steps_per_epoch : int
    visibility, objective : str
    moves : tuple of float
        Move distances of every sensor (m).
    vary_sensors : bool
        Draw per-sensor parameters (altitude in {490, 500, 510}, fov, range band, max_turn,
        depression, SNR) around the SPEC defaults.
    world : MapRect, default 600 x 600
    covs : (M, 4, 4), optional
        Covariances; random (see :func:`random_covariance`) if omitted.
    sensor_kwargs : dict, optional
        Overrides applied to every sensor's :class:`SensorParams`.
    """
    world = world or MapRect()
    W, H = world.width, world.height
    M, N = n_targets, n_sensors
    lo = np.array([0.25 * W, 0.25 * H])
    hi = np.array([0.75 * W, 0.75 * H])
    txy = rng.uniform(lo, hi, size=(M, 2))
    heading = rng.uniform(-math.pi, math.pi, size=M)
    spd = rng.uniform(0.0, speed, size=M)
    means = np.column_stack([txy, spd * np.cos(heading), spd * np.sin(heading)])
    if covs is None:
        covs = np.array([random_covariance(rng, pos_sd, vel_sd) for _ in range(M)])
    sensors, positions, headings = [], [], []
    for i in range(N):
        kw: dict[str, Any] = {"moves": tuple(moves)}
        if vary_sensors:
            kw.update(altitude=float(rng.choice([490.0, 500.0, 510.0])),
                      fov_half_angle=float(rng.uniform(math.pi / 8, math.pi / 4)),
                      min_ground_range=float(rng.uniform(200.0, 260.0)),
                      max_ground_range=float(rng.uniform(430.0, 480.0)),
                      max_turn=float(rng.uniform(math.pi / 8, math.pi / 3)),
                      depression=float(rng.uniform(math.radians(30), math.radians(50))),
                      snr_ref_db=float(rng.uniform(10.0, 20.0)))
        kw.update(sensor_kwargs or {})
        params = SensorParams(**kw)
        j = i % M
        for _ in range(1000):
            b = rng.uniform(-math.pi, math.pi)
            g = rng.uniform(290.0, 410.0)
            p = txy[j] - g * np.array([math.cos(b), math.sin(b)])
            if world.contains(p):
                break
        else:  # pragma: no cover - the middle of the map always has room
            p = rng.uniform([0, 0], [W, H])
        sensors.append(params)
        positions.append(p)
        headings.append(b + rng.uniform(-0.3, 0.3))
    headings = (np.array(headings) + math.pi) % (2 * math.pi) - math.pi
    return PlanningProblem(means=means, covs=covs, positions=np.array(positions),
                           headings=headings, sensors=tuple(sensors), horizon=horizon,
                           steps_per_epoch=steps_per_epoch, dt=dt,
                           process_noise=process_noise, world=world,
                           visibility=visibility, objective=objective)


def random_plan(problem: PlanningProblem, rng: np.random.Generator,
                p_unassigned: float = 0.0) -> Plan:
    """A random feasible plan: each sensor walks random in-map moves epoch by epoch.

    Every epoch's position is one move from the previous epoch's (so it lies in ``R_k`` and
    satisfies every feasibility rule whatever is assigned); each player is unassigned with
    probability ``p_unassigned`` (its position is then NaN), else looks at a uniformly
    random target.
    """
    N, K, M = problem.n_sensors, problem.horizon, problem.n_targets
    positions = np.full((N, K, 2), np.nan)
    targets = np.full((N, K), -1, dtype=np.int64)
    for i, s in enumerate(problem.sensors):
        mv = move_vectors(s.moves)
        p = np.array(problem.positions[i], dtype=float)
        for k in range(K):
            cand = p + mv
            ok = np.flatnonzero(problem.world.contains(cand))
            p = cand[rng.choice(ok)]
            if rng.random() >= p_unassigned:
                positions[i, k] = p
                targets[i, k] = rng.integers(M)
    return Plan(positions, targets)


@pytest.fixture(scope="session")
def problem_factory():
    """:func:`make_problem`, as a fixture."""
    return make_problem


@pytest.fixture(scope="session")
def plan_factory():
    """:func:`random_plan`, as a fixture."""
    return random_plan
