"""Small searching planning problems for the search-reward tests: a Swerling radar, its
closed-form detection probability, an intensity grid and a problem around them."""

from __future__ import annotations

from typing import Any

import numpy as np

from sensorplan.models.sensors import SensorParams
from sensorplan.planners.problem import Plan, PlanningProblem, UndetectedIntensity

SWERLING = SensorParams(detection="swerling1", snr_ref_db=10.0, range_ref=700.0,
                        false_alarm_probability=1e-4)


def swerling_pd(s: SensorParams, ground: float) -> float:
    """Swerling 1, square-law: Pd = Pfa^(1 / (1 + SNR)), SNR = s0 (r_ref / r)^4."""
    r2 = ground * ground + s.altitude * s.altitude
    snr = 10.0 ** (s.snr_ref_db / 10.0) * (s.range_ref * s.range_ref / r2) ** 2
    return float(s.false_alarm_probability ** (1.0 / (1.0 + snr)))


def grid(centres: list[tuple[float, float]], d0: float | list[float], births: float = 0.0,
         survival: float = 1.0, weight: float | None = None) -> UndetectedIntensity:
    """The intensity ``d0`` (one value or one per cell) on cells at ``centres``."""
    C = len(centres)
    return UndetectedIntensity(np.array(centres, dtype=float), np.broadcast_to(d0, (C,)),
                               np.full(C, births), survival, weight=weight)


def problem(positions: list[tuple[float, float]], headings: list[float], u: UndetectedIntensity,
            sectors: int = 4, horizon: int = 1, sensor: SensorParams = SWERLING,
            existence: float | list[float] = 0.0, means: list[list[float]] | None = None,
            steps_per_epoch: int = 1, **settings: Any) -> PlanningProblem:
    """Sensors at ``positions`` searching ``u`` over ``sectors`` sectors, tracks at ``means``
    (one still track at (20, 20) by default) with ``existence``; ``settings`` are further
    :class:`PlanningProblem` fields (objective, reward, ...)."""
    means = means or [[20.0, 20.0, 0.0, 0.0]]
    M = len(means)
    return PlanningProblem(means=np.array(means), covs=np.repeat(np.eye(4)[None] * 50, M, 0),
                           positions=np.array(positions, dtype=float),
                           headings=np.array(headings, dtype=float),
                           sensors=tuple(sensor for _ in positions), horizon=horizon,
                           steps_per_epoch=steps_per_epoch,
                           existence=np.broadcast_to(np.asarray(existence, float), (M,)).copy(),
                           search="on", search_sectors=sectors, undetected=u, **settings)


def sector_plan(prob: PlanningProblem, sectors: list[list[int]]) -> Plan:
    """Every sensor stays where it is and looks at the given sectors."""
    N, K = prob.n_sensors, prob.horizon
    pos = np.repeat(prob.positions[:, None, :], K, axis=1)
    return Plan(pos, np.full((N, K), -1), np.array(sectors))
