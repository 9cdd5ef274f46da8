r"""Global nearest neighbour (GNN) tracking with M-of-N track logic: the engineer's baseline.

``tracker.kind = "gnn"``. Each track is one constant-velocity EKF (the PMB's Bernoulli
density without its existence) with a label for life and a status, tentative or confirmed.
Its parts, in Stone Soup's words:

- **Predictor**: the Kalman prediction of the map model's motion
  (:class:`~sensorplan.tracking.pmb.map_tracker.MapModel`, the PMB tracker's: CWNA with
  ``process_noise``, or a given ``motion = (F, Q)``), as the PMB predicts a Bernoulli.
  The map's edge (``map_edge``): with ``exit`` (a target that reaches the edge leaves and
  is gone) a track whose predicted mean leaves the map is deleted; with ``closed`` (targets
  turn back at the walls) its density is reflected back in as the PMB's
  (:func:`sensorplan.tracking.known_map.map_edge_predict`).
- **Data associator** (each look, in sensor order, with detections :math:`z_1..z_m`): one
  2-D assignment (:func:`gnn_assignment`, ``scipy.optimize.linear_sum_assignment``) over
  the gated (track, detection) pairs. Pair :math:`(i, j)` costs the negative log of its
  likelihood ratio against "track :math:`i` missed, :math:`z_j` clutter",

  .. math::
      c_{ij} = -\ln \frac{P_{d,i}\, N(z_j;\ h_i, S_i)}{(1 - P_{d,i} v_i)\, \kappa(z_j)},

  with :math:`P_{d,i}` the detection probability at the track's predicted position,
  :math:`v_i = 1` when the predicted mean lies in the look's sensing region and in sight
  (else 0), :math:`\kappa` the clutter intensity (both terms of the ratio floored at
  :data:`~sensorplan.tracking.pmb.tracker.MIN_WEIGHT`, so that a sure detection or no
  clutter still gives finite costs). Leaving a track unassigned costs 0: the
  assignment maximises the joint likelihood ratio. Gating, likelihoods, :math:`P_d`,
  :math:`v` and :math:`\kappa` are the PMB's (:mod:`sensorplan.tracking.pmb.sensing`,
  :func:`~sensorplan.tracking.pmb.bernoulli.pair_terms`).
- **Updater**: the assigned tracks' EKF updates (the PMB's, Joseph form). An unassigned
  track keeps its prediction (no missed-look update of its density).
- **Initiator**: every unassigned detection starts a tentative track with the density the
  PMB gives a target first seen in it (:func:`~sensorplan.tracking.pmb.bernoulli.first_detection`:
  the grid cells' components with the velocity prior, gated, updated, moment matched;
  every cell weighted by :math:`P_d v` at its centre, a uniform undetected intensity). A
  detection that no cell gates (off the map) starts nothing.
- **Deleter** (M-of-N logic). *A look at a track* is a look whose sensing region contains
  the track's predicted mean, in sight (:math:`v_i = 1`), or one whose detection is
  assigned to it. A tentative track counts its looks from the one that started it (a hit)
  and is confirmed at ``confirm_hits`` hits within its first ``confirm_looks`` looks; it is
  deleted as soon as that can no longer happen. Any track is deleted after
  ``delete_misses`` consecutive missed looks at it. A look that does not cover a track
  neither confirms nor deletes it.

**Reporting**: :meth:`GNNTracker.tracks` reports the confirmed tracks, labels ascending,
with existence 1 (a GNN tracker has no probability of existence; confirmation is its
decision that the track is real).

The defaults, 2 hits in 3 looks to confirm and 5 missed looks to delete, are the common
radar ones: the history logic of Blackman and Popoli (1999, "Design and Analysis of Modern
Tracking Systems"), with the defaults of MATLAB's ``radarTracker`` and ``trackerGNN``
(``ConfirmationThreshold [2 3]``, ``DeletionThreshold [5 5]``).
"""

from __future__ import annotations


import numpy as np
from scipy.optimize import linear_sum_assignment

from .._types import BoolArray, FloatArray, IntArray
from .base import Looks, TrackSet, UpdateRecord, given_tracks
from .ekf import predict as kalman_predict
from .known_map import map_edge_predict
from .pmb.bernoulli import PairTerms, first_detection, pair_terms, updates
from .pmb.sensing import Look
from .pmb.map_tracker import MapModel, MapTracker, looks_in_order
from .pmb.tracker import MIN_WEIGHT

#: The M-of-N defaults: (confirm_hits, confirm_looks, delete_misses).
DEFAULT_LOGIC = (2, 3, 5)


def gnn_assignment(cost: FloatArray) -> IntArray:
    """The assignment of tracks to detections of least total cost, a track unassigned at 0.

    Parameters
    ----------
    cost : (n, m) float   the cost of each (track, detection) pair; ``inf`` where the pair
                          is not gated (not allowed)

    Returns
    -------
    (n,) int   each track's detection, -1 when it is unassigned; no detection twice
    """
    cost = np.asarray(cost, dtype=float)
    n, m = cost.shape
    out = np.full(n, -1, dtype=np.int64)
    ok = np.isfinite(cost)
    rows, cols = np.flatnonzero(ok.any(axis=1)), np.flatnonzero(ok.any(axis=0))
    if rows.size == 0:
        return out
    # One dummy column per track ("unassigned", cost 0, only its own): every row has a
    # feasible choice, so the rectangular problem always has a solution.
    dummy = np.full((rows.size, rows.size), np.inf)
    np.fill_diagonal(dummy, 0.0)
    r, c = linear_sum_assignment(np.hstack([cost[np.ix_(rows, cols)], dummy]))
    real = c < cols.size
    out[rows[r[real]]] = cols[c[real]]
    return out


class GNNTracker(MapTracker):
    """Global nearest neighbour tracker with M-of-N confirmation and deletion (see the
    module docstring).

    Parameters
    ----------
    model : MapModel
        The sensors, the motion model, the map and its grid of initiator cells, the gate,
        the map's edge and the buildings (the PMB tracker's). With ``map_edge = "exit"`` a
        track whose predicted mean leaves the map is deleted; with ``"closed"`` its density
        is reflected back in.
    means : (M, 4), optional
        Targets known at the start: confirmed tracks labelled ``0..M-1``.
    covs : (M, 4, 4) or (4, 4), optional
        Their covariances (needed with ``means``).
    confirm_hits, confirm_looks : int
        A tentative track is confirmed at ``confirm_hits`` hits within its first
        ``confirm_looks`` looks (1 <= hits <= looks); default 2 of 3.
    delete_misses : int >= 1
        A track is deleted after this many consecutive missed looks at it; default 5.
    """

    def __init__(self, model: MapModel, *, means: FloatArray | None = None,
                 covs: FloatArray | None = None, confirm_hits: int = DEFAULT_LOGIC[0],
                 confirm_looks: int = DEFAULT_LOGIC[1],
                 delete_misses: int = DEFAULT_LOGIC[2]) -> None:
        if not 1 <= int(confirm_hits) <= int(confirm_looks):
            raise ValueError(f"need 1 <= confirm_hits <= confirm_looks, got {confirm_hits!r} "
                             f"and {confirm_looks!r}")
        if int(delete_misses) < 1:
            raise ValueError(f"delete_misses must be >= 1, got {delete_misses!r}")
        super().__init__(model)
        self.confirm_hits, self.confirm_looks = int(confirm_hits), int(confirm_looks)
        self.delete_misses = int(delete_misses)
        m0, P0 = given_tracks(means, covs)
        M = len(m0)
        self.means, self.covs = m0, P0
        self.labels = np.arange(M, dtype=np.int64)
        self.confirmed = np.ones(M, dtype=bool)
        self.hits = np.zeros(M, dtype=np.int64)       # hits and looks while tentative
        self.looks = np.zeros(M, dtype=np.int64)
        self.misses = np.zeros(M, dtype=np.int64)     # consecutive missed looks
        self.next_label = M

    # ---------------------------------------------------------------- the tracker protocol
    def tracks(self) -> TrackSet:
        """The confirmed tracks (copies), existence 1."""
        k = self.confirmed
        return TrackSet(self.means[k].copy(), self.covs[k].copy(),
                        np.ones(int(k.sum())), self.labels[k].copy())

    def planning_process_noise(self) -> float | FloatArray:
        """q of the CWNA motion model the planner predicts every track with."""
        return self.process_noise

    def predict(self) -> BoolArray:
        """Predict every track one step (and delete those that left the map with ``map_edge
        = "exit"``, reflect them back in with ``"closed"``); returns ``(T,)``: the reported
        tracks the map's edge changed (always False with ``exit``)."""
        T = int(self.confirmed.sum())
        if len(self.labels):
            self.means, self.covs = kalman_predict(self.means, self.covs, self.F, self.Q)
            if self.map_edge == "closed":
                before = self.confirmed.copy()
                self.means, self.covs, applied, _ = map_edge_predict(
                    self.means, self.covs, *self.world, "closed")
                return applied[before]
            if self.map_edge == "exit":
                x, y = self.means[:, 0], self.means[:, 1]
                self._keep((x >= 0.0) & (x <= self.world[0]) & (y >= 0.0)
                           & (y <= self.world[1]))
        return np.zeros(T, dtype=bool)

    def update(self, looks: Looks) -> UpdateRecord:
        """Update with one step's looks, in the given (sensor) order; the looks' aims are
        not used.

        The record's ``negative`` marks the tracks reported before the update that a look
        looked at and missed.
        """
        L = len(looks.sensors)
        reported = self.labels[self.confirmed]
        T = len(reported)
        missed_labels: list[IntArray] = []
        used = np.zeros(L, dtype=np.int64)
        discarded = np.zeros(L, dtype=np.int64)
        for n, (look, Z) in enumerate(looks_in_order(looks)):
            used[n], discarded[n], missed = self.update_look(look, Z)
            missed_labels.append(missed)
        negative = np.isin(reported, np.concatenate(missed_labels)) if L else np.zeros(
            T, dtype=bool)
        zeros = np.zeros(T, dtype=bool)
        return UpdateRecord(negative, zeros, zeros.copy(), zeros.copy(), used, discarded)

    # ---------------------------------------------------------------- one look
    def costs(self, look: Look, Z: FloatArray) -> tuple[FloatArray, BoolArray, PairTerms]:
        """The assignment costs ``(n, m)`` of the tracks and detections ``Z (m, 2)`` (inf
        outside the gate), which tracks the look looks at ``(n,)``, and the pair terms."""
        s = self.sensing
        xy = self.means[:, :2]
        v = s.detectable(xy, look) if len(xy) else np.zeros(0)
        terms = pair_terms(s, look, self.means, self.covs, Z, self.gate)
        pd = s.detection_probability(xy, look)
        w_miss = np.maximum(1.0 - v, MIN_WEIGHT)
        kappa = np.maximum(s.clutter(Z, look), MIN_WEIGHT)
        with np.errstate(divide="ignore"):
            log_ratio = (terms.log_lik + np.log(pd)[:, None] - np.log(w_miss)[:, None]
                         - np.log(kappa)[None])
        cost = np.where(terms.gated, -log_ratio, np.inf)
        return cost, v > 0.0, terms

    def update_look(self, look: Look, Z: FloatArray) -> tuple[int, int, IntArray]:
        """Associate, update, initiate and apply the track logic for one look's
        detections ``Z (m, 2)``.

        Returns
        -------
        used : int          detections assigned to a track
        discarded : int     detections assigned to none that started no track
        missed : (k,) int   labels of the tracks the look looked at and missed
        """
        n, m = len(self.labels), len(Z)
        assigned = np.full(n, -1, dtype=np.int64)
        terms: PairTerms | None = None
        if n:
            if m:
                cost, looked, terms = self.costs(look, Z)
                assigned = gnn_assignment(cost)
            else:
                looked = self.sensing.detectable(self.means[:, :2], look) > 0.0
            hit = assigned >= 0
            rows = np.flatnonzero(hit)
            if rows.size and terms is not None:
                x, P = updates(self.means, self.covs, terms, rows,
                               np.arange(rows.size), assigned[rows])
                self.means, self.covs = self.means.copy(), self.covs.copy()
                self.means[rows], self.covs[rows] = x, P
            miss = looked & ~hit
            counted = hit | miss
            tentative = ~self.confirmed
            self.looks = self.looks + (counted & tentative)
            self.hits = self.hits + (hit & tentative)
            self.misses = np.where(hit, 0, self.misses + miss)
            missed = self.labels[miss]
            self.confirmed = self.confirmed | (tentative & (self.hits >= self.confirm_hits))
            dead = self.misses >= self.delete_misses
            # A tentative track that can no longer reach its hits in its looks.
            dead |= ~self.confirmed & (self.hits + (self.confirm_looks - self.looks)
                                       < self.confirm_hits)
            keep = ~dead
        else:
            missed, keep = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool)
        unassigned = np.ones(m, dtype=bool)
        unassigned[assigned[assigned >= 0]] = False
        free = np.flatnonzero(unassigned)
        started = 0
        if free.size:
            detect = self.sensing.detectable(self.grid.centres, look)
            cells = np.flatnonzero(detect > 0.0)
            found, x0, P0 = first_detection(self.sensing, look, self._cell_means[cells],
                                            self._cell_covs[:cells.size], detect[cells],
                                            Z[free], self.gate)
            started = x0.shape[0]
        self._keep(keep)
        if started:
            k = started
            self.means = np.concatenate([self.means, x0])
            self.covs = np.concatenate([self.covs, P0])
            self.labels = np.concatenate([self.labels, np.arange(
                self.next_label, self.next_label + k, dtype=np.int64)])
            self.next_label += k
            # The starting detection is the new track's first look and first hit.
            one = np.ones(k, dtype=np.int64)
            self.confirmed = np.concatenate([self.confirmed,
                                             np.full(k, self.confirm_hits <= 1)])
            self.hits = np.concatenate([self.hits, one])
            self.looks = np.concatenate([self.looks, one])
            self.misses = np.concatenate([self.misses, 0 * one])
        n_used = int(np.count_nonzero(assigned >= 0))
        return n_used, int(free.size - started), missed

    def _keep(self, keep: BoolArray) -> None:
        if not keep.all():
            self.means, self.covs = self.means[keep], self.covs[keep]
            self.labels, self.confirmed = self.labels[keep], self.confirmed[keep]
            self.hits, self.looks = self.hits[keep], self.looks[keep]
            self.misses = self.misses[keep]


__all__ = ["DEFAULT_LOGIC", "GNNTracker", "gnn_assignment"]
