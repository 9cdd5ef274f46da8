"""How well a CWNA motion model with process noise q describes the recorded traffic truth.

For every pair of consecutive live steps of an aircraft the one-step residual
``w = x_{k+1} - F x_k`` of the truth's own state (position and velocity) is scored by
``w^T Q(q)^-1 w`` with the CWNA covariance ``Q(q) = q [[T^3/3, T^2/2], [T^2/2, T]]`` per
axis. A model whose q fits the motion scores 4 on average (the state's dimension), so the
q whose mean score is 4 is the truth's own, measured without any sensor or tracker: a
filter with a larger q is under-confident on this motion, a smaller one over-confident.
The score is linear in 1/q, so one computation at q = 1 gives every q.

``--modes R`` also fits the motion of an interacting multiple model filter to the same
residuals: R CWNA modes with their own q and a Markov switching matrix, the hidden Markov
model whose maximum-likelihood parameters the Baum-Welch (EM) iterations find, each
aircraft's residuals one sequence. A residual is Gaussian with covariance q Q(1) under a
mode with q, so the M-step's q is closed form: the mode-weighted mean score over 4.

    python scripts/traffic_motion_q.py [--q 25 32 50 100] [--modes 2]
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


def score_sequences(states: np.ndarray, dt: float) -> list[np.ndarray]:
    """Each aircraft's :func:`motion_scores` in time order (one array per aircraft with at
    least one residual)."""
    out = [motion_scores(states[:, j:j + 1], dt) for j in range(states.shape[1])]
    return [s for s in out if len(s)]


def fit_modes(sequences: list[np.ndarray], n_modes: int, iterations: int = 200,
              tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, float]:
    """Maximum-likelihood CWNA modes of residual score sequences, by Baum-Welch.

    Parameters
    ----------
    sequences : list of (n_k,)   each aircraft's scores ``w^T Q(1)^-1 w`` in time order
    n_modes : int                R
    iterations : int             at most this many EM iterations
    tol : float                  stop when the log-likelihood gains less (relative)

    Returns
    -------
    q : (R,) ascending           each mode's q (m^2/s^3)
    switching : (R, R)           ``P(mode j at k+1 | mode i at k)``, rows summing to 1
    log_lik : float              the log-likelihood reached (up to a constant)
    """
    R = int(n_modes)
    pooled = np.concatenate(sequences)
    # Start from quantiles of the pooled per-residual q's, switching mostly staying.
    q = np.quantile(pooled / 4.0, np.linspace(0.3, 0.9, R)) if R > 1 else np.array(
        [pooled.mean() / 4.0])
    Pi = np.full((R, R), 0.1 / max(R - 1, 1)) + np.eye(R) * (0.9 - 0.1 / max(R - 1, 1))
    if R == 1:
        Pi = np.ones((1, 1))
    start = np.full(R, 1.0 / R)
    previous = -np.inf
    log_lik = -np.inf
    for _ in range(iterations):
        num_q, den_q = np.zeros(R), np.zeros(R)
        trans, first = np.zeros((R, R)), np.zeros(R)
        log_lik = 0.0
        for s in sequences:
            # Emission densities up to the factor common to every mode (the 4-d Gaussian's
            # -2 ln q - s / (2 q)), scaled per step by their maximum.
            log_e = -0.5 * s[:, None] / q[None] - 2.0 * np.log(q)[None]
            shift = log_e.max(axis=1, keepdims=True)
            e = np.exp(log_e - shift)
            n = len(s)
            alpha, c = np.empty((n, R)), np.empty(n)
            a = start * e[0]
            c[0] = a.sum()
            alpha[0] = a / c[0]
            for k in range(1, n):
                a = (alpha[k - 1] @ Pi) * e[k]
                c[k] = a.sum()
                alpha[k] = a / c[k]
            beta = np.ones((n, R))
            for k in range(n - 2, -1, -1):
                beta[k] = (Pi @ (e[k + 1] * beta[k + 1])) / c[k + 1]
            gamma = alpha * beta
            gamma /= gamma.sum(axis=1, keepdims=True)
            if n > 1:
                xi = (alpha[:-1, :, None] * Pi[None] * (e[1:] * beta[1:])[:, None, :]
                      / c[1:, None, None])
                trans += xi.sum(axis=0)
            first += gamma[0]
            num_q += gamma.T @ s
            den_q += gamma.sum(axis=0)
            log_lik += float(np.log(c).sum() + shift.sum())
        q = num_q / (4.0 * np.maximum(den_q, 1e-300))
        if R > 1:
            Pi = trans / np.maximum(trans.sum(axis=1, keepdims=True), 1e-300)
        start = first / first.sum()
        if abs(log_lik - previous) <= tol * abs(log_lik):
            break
        previous = log_lik
    order = np.argsort(q)
    return q[order], Pi[np.ix_(order, order)], log_lik


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--q", type=float, nargs="+", default=[25.0, 32.0, 50.0, 100.0])
    ap.add_argument("--modes", type=int, nargs="*", default=[],
                    help="also fit IMMs with these numbers of modes (e.g. 2 3)")
    args = ap.parse_args(argv)
    states = load_flights().states
    s = motion_scores(states, TRAFFIC.dt)
    print(f"{len(s)} one-step residuals; the q whose mean score is 4: {s.mean() / 4:.1f} "
          f"m^2/s^3 (median score 4 at q = {np.median(s) / 4:.1f})")
    print("| q (m^2/s^3) | mean score (4 fits) | share above 13.28 (1 % fits) |")
    print("|--:|--:|--:|")
    for q in args.q:
        print(f"| {q:g} | {s.mean() / q:.2f} | {100 * np.mean(s / q > 13.28):.1f} % |")
    sequences = score_sequences(states, TRAFFIC.dt)
    for R in args.modes:
        q, Pi, ll = fit_modes(sequences, R)
        probs = _stationary(Pi)
        print(f"\n{R} modes, maximum likelihood over {len(sequences)} aircraft "
              f"(log-likelihood {ll:.1f} up to a constant):")
        print("| mode | q (m^2/s^3) | share of steps | mean stay (steps) | switching row |")
        print("|--:|--:|--:|--:|---|")
        for i in range(R):
            stay = 1.0 / max(1.0 - Pi[i, i], 1e-12)
            row = ", ".join(f"{p:.4f}" for p in Pi[i])
            print(f"| {i} | {q[i]:.2f} | {probs[i]:.3f} | {stay:.1f} | {row} |")


def _stationary(Pi: np.ndarray) -> np.ndarray:
    R = len(Pi)
    A = np.vstack([Pi.T - np.eye(R), np.ones((1, R))])
    b = np.r_[np.zeros(R), 1.0]
    return np.linalg.lstsq(A, b, rcond=None)[0]


if __name__ == "__main__":
    main()
