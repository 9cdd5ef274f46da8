"""PMB data association's belief propagation written out twice in plain numpy: the tests'
second computations of :func:`sensorplan.tracking.pmb.association.association_lbp`.

* :func:`lbp_dense`: Williams and Lau (2014)'s ratio-form messages on dense ``(n, m)``
  arrays, the slow readable version of the compiled edge-list kernel (the same
  equations; "all others" sums as a total minus one term, which is fine for the weights
  the tests draw). The benchmark times it against the kernel.
* :func:`lbp_generic`: textbook sum-product belief propagation on the pairwise factor graph
  of track variables ``a_i`` (0 missed, ``j + 1`` measurement ``j``) and measurement
  variables ``b_j`` (0 new or clutter, ``i + 1`` track ``i``), with full vector messages and
  an explicit consistency factor per gated pair. It shares nothing with the ratio form: on a
  loopy graph its fixed point checks that the ratio-form messages are right, where the exact
  marginals cannot.

Both share no code with the library.
"""

from __future__ import annotations

import numpy as np

FloatArray = np.ndarray


def lbp_dense(w_miss: FloatArray, w_det: FloatArray, w_new: FloatArray, tol: float = 1e-10,
              max_iter: int = 1000) -> tuple[FloatArray, FloatArray, FloatArray, int, bool]:
    """``(p_det (n, m), p_miss (n,), p_new (m,), iterations, converged)``."""
    n, m = w_det.shape
    psi = w_det / w_miss[:, None]                   # the miss weight becomes 1
    gated = psi > 0.0
    nu = np.where(gated, 1.0 / w_new, 0.0)          # no competing track yet
    iterations, converged = 0, not gated.any()
    while not converged and iterations < max_iter:
        iterations += 1
        s = psi * nu
        mu = psi / (1.0 + s.sum(axis=1, keepdims=True) - s)
        nu_next = np.where(gated, 1.0 / (w_new + mu.sum(axis=0) - mu), 0.0)
        change = np.max(np.abs(nu_next - nu)[gated] / nu_next[gated])
        nu, converged = nu_next, change <= tol
    s = psi * nu
    a = 1.0 + s.sum(axis=1)
    mu = psi / (a[:, None] - s)
    p_new = w_new / (w_new + mu.sum(axis=0))
    return s / a[:, None], 1.0 / a, p_new, iterations, converged


def lbp_generic(w_miss: FloatArray, w_det: FloatArray, w_new: FloatArray, tol: float = 1e-13,
                max_iter: int = 5000) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(p_det (n, m), p_miss (n,), p_new (m,))``: beliefs at the fixed point of
    flooding-schedule sum-product on the factor graph (slow: small problems only)."""
    n, m = w_det.shape
    edges = [(i, j) for i in range(n) for j in range(m) if w_det[i, j] > 0.0]
    # Unary factors: a_i in {miss, 0..m-1}, b_j in {new, track 0..n-1}; b_j = i is
    # impossible when the pair is not gated.
    phi_a = [np.r_[w_miss[i], w_det[i]] for i in range(n)]
    phi_b = [np.r_[w_new[j], (w_det[:, j] > 0.0).astype(float)] for j in range(m)]
    consistent = {}                                  # (m + 1, n + 1): a_i = j iff b_j = i
    for i, j in edges:
        c = np.ones((m + 1, n + 1))
        c[j + 1, :] = 0.0
        c[:, i + 1] = 0.0
        c[j + 1, i + 1] = 1.0
        consistent[i, j] = c
    to_b = {e: np.full(n + 1, 1.0 / (n + 1)) for e in edges}     # a_i -> b_j
    to_a = {e: np.full(m + 1, 1.0 / (m + 1)) for e in edges}     # b_j -> a_i
    for _ in range(max_iter):
        new_b, new_a = {}, {}
        for i, j in edges:
            into_a = phi_a[i] * np.prod([to_a[e] for e in edges if e[0] == i and e[1] != j]
                                        + [np.ones(m + 1)], axis=0)
            v = into_a @ consistent[i, j]
            new_b[i, j] = v / v.sum()
            into_b = phi_b[j] * np.prod([to_b[e] for e in edges if e[1] == j and e[0] != i]
                                        + [np.ones(n + 1)], axis=0)
            v = consistent[i, j] @ into_b
            new_a[i, j] = v / v.sum()
        change = max((np.max(np.abs(new_a[e] - to_a[e])) for e in edges), default=0.0)
        change = max([change] + [np.max(np.abs(new_b[e] - to_b[e])) for e in edges])
        to_b, to_a = new_b, new_a
        if change <= tol:
            break
    p_det, p_miss, p_new = np.zeros((n, m)), np.zeros(n), np.zeros(m)
    for i in range(n):
        belief = phi_a[i] * np.prod([to_a[e] for e in edges if e[0] == i] + [np.ones(m + 1)],
                                    axis=0)
        belief /= belief.sum()
        p_miss[i], p_det[i] = belief[0], belief[1:]
    for j in range(m):
        belief = phi_b[j] * np.prod([to_b[e] for e in edges if e[1] == j] + [np.ones(n + 1)],
                                    axis=0)
        p_new[j] = belief[0] / belief.sum()
    return p_det, p_miss, p_new
