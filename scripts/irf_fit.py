"""The clutter factor of detection-aware planning: evaluate and fit it.

The information reduction factor (IRF) of a probabilistic data association filter is the
Fisher information of one look, relative to a look whose single detection is certainly the
target's (Niu, Willett and Bar-Shalom, "Matrix CRLB scaling due to measurements of
uncertain origin", IEEE Trans. Signal Processing 49(7), 2001; Kershaw and Evans, "Optimal
waveform selection for tracking systems", IEEE Trans. Information Theory 40(5), 1994).
In whitened measurement coordinates (innovation covariance I, 2-D), with detection
probability Pd, a gate of radius g (gate probability Pg = 1 - exp(-g^2/2)) and Poisson
clutter of density lam per unit whitened area, the likelihood of the detections Z in the
gate is, up to factors free of the target position theta,
    (1 - Pd Pg) lam + Pd sum_i N(z_i; theta, I)   (times lam^(m-1)),
and the IRF is E|d/dtheta log p(Z | theta)|^2 / 2 at theta = 0.

This script estimates it by Monte Carlo on a grid of (Pd, lam), divides by its clutter-free
value Pd (1 - (1 + g^2/2) exp(-g^2/2)) so that the clutter factor q2 is 1 without clutter,
and fits Kershaw and Evans's functional form
    q2(Pd, lam) = 1 / (1 + b Pd^-c lam^d)
by least squares on log q2 (relative errors: the planner's objective is a log-det). Run
once; its output is in docs/model.md and the constants in sensorplan/models/radar.py:

    python scripts/irf_fit.py            (about 10 min on 2 cores)
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2

GATE_PROBABILITY = 0.999
PDS = (0.3, 0.5, 0.7, 0.9, 1.0)
LAMS = (0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0)


def irf(pd: float, lam: float, rng: np.random.Generator, n: int = 200_000,
        batch: int = 20_000) -> tuple[float, float]:
    """Monte Carlo IRF (and its standard error) at one (Pd, lam)."""
    g2 = chi2.ppf(GATE_PROBABILITY, 2)
    g = math.sqrt(g2)
    V = math.pi * g2
    b = (1.0 - pd * GATE_PROBABILITY) * lam / pd
    vals = []
    for _ in range(n // batch):
        m = rng.poisson(lam * V, batch)
        zt = rng.standard_normal((batch, 2))
        det = (rng.random(batch) < pd) & ((zt ** 2).sum(1) <= g2)
        mmax = max(int(m.max()), 1)
        r = g * np.sqrt(rng.random((batch, mmax)))
        a = rng.uniform(0.0, 2.0 * math.pi, (batch, mmax))
        zc = np.stack([r * np.cos(a), r * np.sin(a)], -1)
        valid = np.arange(mmax)[None] < m[:, None]
        Nc = np.exp(-0.5 * (zc ** 2).sum(-1)) / (2 * math.pi) * valid
        Nt = np.exp(-0.5 * (zt ** 2).sum(-1)) / (2 * math.pi) * det
        num = (Nc[..., None] * zc).sum(1) + Nt[:, None] * zt
        den = b + Nc.sum(1) + Nt
        vals.append((num ** 2).sum(1) / den ** 2 / 2.0)
    v = np.concatenate(vals)
    return float(v.mean()), float(v.std() / math.sqrt(v.size))


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0],
                            epilog="Takes no arguments; about 10 min on 2 cores."
                            ).parse_args(argv)
    rng = np.random.default_rng(20261201)
    g2 = chi2.ppf(GATE_PROBABILITY, 2)
    free = 1.0 - (1.0 + g2 / 2.0) * math.exp(-g2 / 2.0)
    rows = []
    for pd in PDS:
        for lam in LAMS:
            q, se = irf(pd, lam, rng)
            q2 = q / (pd * free)
            rows.append((pd, lam, q2, se / (pd * free)))
            print(f"Pd {pd:.2f} lam {lam:7.3f}: q2 {q2:.4f} +- {se / (pd * free):.4f}",
                  flush=True)
    data = np.array(rows)

    def model(theta: np.ndarray) -> np.ndarray:
        b, c, d = theta
        return 1.0 / (1.0 + b * data[:, 0] ** -c * data[:, 1] ** d)

    fit = least_squares(lambda th: np.log(model(th)) - np.log(data[:, 2]), x0=[20.0, 1.0, 1.0])
    b, c, d = fit.x
    err = model(fit.x) - data[:, 2]
    print(f"\nfit: q2 = 1 / (1 + {b:.4g} Pd^-{c:.4g} lam^{d:.4g}); max |error| "
          f"{np.abs(err).max():.4f}, mean {np.abs(err).mean():.4f}, max relative error "
          f"{np.abs(err / data[:, 2]).max():.3f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
