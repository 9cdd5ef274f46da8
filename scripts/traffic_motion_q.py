"""How well a CWNA motion model with process noise q describes the recorded traffic truth.

For every pair of consecutive live steps of an aircraft the one-step residual
``w = x_{k+1} - F x_k`` of the truth's own state (position and velocity) is scored by
``w^T Q(q)^-1 w`` with the CWNA covariance ``Q(q) = q [[T^3/3, T^2/2], [T^2/2, T]]`` per
axis. A model whose q fits the motion scores 4 on average (the state's dimension), so the
q whose mean score is 4 is the truth's own, measured without any sensor or tracker: a
filter with a larger q is under-confident on this motion, a smaller one over-confident.
The score is linear in 1/q, so one computation at q = 1 gives every q.

    python scripts/traffic_motion_q.py [--q 25 32 50 100]
"""

from __future__ import annotations

import argparse

import numpy as np

from sensorplan.models.traffic import TRAFFIC, load_flights


def motion_scores(states: np.ndarray, dt: float) -> np.ndarray:
    """``w^T Q(1)^-1 w`` of every one-step residual of ``states`` ``(S + 1, M, 4)``, NaN
    outside a life (:class:`~sensorplan.models.traffic.Flights`)."""
    a, b = states[:-1], states[1:]
    live = np.isfinite(a[..., 0]) & np.isfinite(b[..., 0])
    a, b = a[live], b[live]
    w = b - np.c_[a[:, :2] + dt * a[:, 2:], a[:, 2:]]
    q1 = np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    # Per axis: (position residual, velocity residual), scored against Q(1) by a solve.
    per_axis = np.stack([w[:, [0, 2]], w[:, [1, 3]]])               # (2, n, 2)
    solved = np.linalg.solve(q1, per_axis.reshape(-1, 2).T).T.reshape(per_axis.shape)
    return np.einsum("anj,anj->n", per_axis, solved)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--q", type=float, nargs="+", default=[25.0, 32.0, 50.0, 100.0])
    args = ap.parse_args(argv)
    s = motion_scores(load_flights().states, TRAFFIC.dt)
    print(f"{len(s)} one-step residuals; the q whose mean score is 4: {s.mean() / 4:.1f} "
          f"m^2/s^3 (median score 4 at q = {np.median(s) / 4:.1f})")
    print("| q (m^2/s^3) | mean score (4 fits) | share above 13.28 (1 % fits) |")
    print("|--:|--:|--:|")
    for q in args.q:
        print(f"| {q:g} | {s.mean() / q:.2f} | {100 * np.mean(s / q > 13.28):.1f} % |")


if __name__ == "__main__":
    main()
