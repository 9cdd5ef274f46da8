r"""The track-oriented Poisson multi-Bernoulli (PMB) tracker.

Williams (2015, "Marginal multi-Bernoulli filters: RFS derivation of MHT, JIPDA and
association-based MeMBer") and García-Fernández, Williams, Granström and Svensson (2018,
"Poisson multi-Bernoulli mixture filter: direct derivation and implementation"): the
targets are the union of a Poisson process of targets never detected (intensity
:math:`D_u`, :mod:`sensorplan.tracking.pmb.undetected`) and independent Bernoullis, each a
target that exists with probability :math:`r_i` with a Gaussian density
(:mod:`sensorplan.tracking.pmb.bernoulli`). It meets the tracker protocol of
:mod:`sensorplan.tracking.base` for the radar and for the linear position sensor
(:mod:`sensorplan.tracking.pmb.sensing`). The sensors, the motion, the map and its grid,
the gate and the map's edge are one :class:`~sensorplan.tracking.pmb.map_tracker.MapModel`,
which the GNN tracker takes too.

**Predict** (every step). Each Bernoulli: the motion model's Kalman prediction (CWNA with
the model's ``process_noise``, or a given ``motion = (F, Q)``) and :math:`r \leftarrow p_S r`.
The map's edge (``map_edge``, :func:`sensorplan.tracking.known_map.map_edge_predict`):
with ``exit`` (a target that reaches the edge leaves and is gone) the survival also
requires the target to stay on the map: a density whose mean or 3-sigma box leaves it is
truncated to the map and :math:`r` is multiplied by its mass on the map (``edge_exit =
"outside"``), or by the probability that a target on the map at the step's start is still
on it at the end (``"crossing"``: a live target is on the map, so the part of the density
already off it is not charged again each step); with ``closed``
(targets turn back at the walls) the part beyond a wall is reflected back in and
:math:`r` loses nothing at the edge. :math:`D_u`: survival and births.

**Update** (each look, in sensor order, with its detections :math:`z_1..z_m`):

1. Every Bernoulli's missed-look hypothesis: :math:`\bar P_i`, its detection probability
   integrated over its density by the missed-look quadrature (occlusion included), and its
   density given no detection, the quadrature's weighted moments
   (:func:`~sensorplan.tracking.pmb.bernoulli.missed_look`: the known-target tracker's
   rule for imperfect detection, without its inflation).
2. Gating: detection :math:`j` is a candidate for Bernoulli :math:`i` when its innovation's
   squared Mahalanobis distance is below the chi-square(2) quantile of
   ``gate_probability``; likewise for the cells of :math:`D_u`.
3. Weights: miss :math:`1 - r_i + r_i (1 - \bar P_i) = 1 - r_i \bar P_i`; detection
   :math:`r_i P_d\, l_{ij}` (``l`` the Gaussian likelihood, 0 outside the gate, ``P_d`` at
   the Bernoulli's predicted position); new :math:`\lambda_u(z_j) + \kappa(z_j)`
   (undetected intensity's detection weight plus the clutter intensity). Marginal
   association probabilities by loopy belief propagation
   (:func:`~sensorplan.tracking.pmb.association.association_lbp`).
4. Track-oriented merge. Bernoulli :math:`i` becomes the mixture of its hypotheses: missed
   (weight :math:`p^{miss}_i`, existence :math:`r_i (1 - \bar P_i) / (1 - r_i \bar P_i)`,
   the missed-look density) and detected by :math:`z_j` (weight :math:`p^{det}_{ij}`,
   existence 1, the EKF update), so
   :math:`r'_i = p^{miss}_i r^{miss}_i + \sum_j p^{det}_{ij}`, and its density the
   moment-matched mixture with weights :math:`p^{miss}_i r^{miss}_i / r'_i` and
   :math:`p^{det}_{ij} / r'_i`. A Bernoulli that the look could not have detected
   (:math:`\bar P_i = 0`) and that gates no detection is left exactly as it was.
5. Each detection :math:`z_j` starts a Bernoulli with existence
   :math:`p^{new}_j\, \lambda_u(z_j) / (\lambda_u(z_j) + \kappa(z_j))` and the density of
   the gated cells' components updated by :math:`z_j`, weighted by their shares of
   :math:`\lambda_u(z_j)` and moment matched; it gets the next unused label. One below
   the pruning threshold is not created (its label is not used).
6. :math:`D_u` is thinned by the look; Bernoullis with :math:`r` below
   ``prune_threshold`` are dropped, or, with recycling on, those below
   ``recycle_threshold`` are recycled.

**Recycling** (Williams 2012, "Hybrid Poisson and multi-Bernoulli filters", FUSION; off
by default). With ``recycle_threshold > 0``, a Bernoulli whose existence falls below it
(after a prediction or a look) is not dropped but approximated as a Poisson component:
:math:`r\, N(m, P)` is added to :math:`D_u` by its position marginal's mass in each cell
(:func:`~sensorplan.tracking.pmb.undetected.recycle`; the grid's total rises by exactly
:math:`r`). The intensity then carries the target where it went: looks thin it,
predictions keep it, and a later detection there starts a Bernoulli from it (with a new
label). Recycling replaces pruning: no Bernoulli is dropped, and ``prune_threshold`` only
keeps a detection from starting a Bernoulli below it; so ``recycle_threshold`` may not be
below ``prune_threshold``, nor at or above ``report_threshold`` (a reported track would
be recycled at once).

Missed looks are the same update with no detection: step 4 leaves :math:`r'_i` and the
missed-look density. The missed-look probability :math:`\bar P` ignores the gate (a
target detected outside its gate would start a new Bernoulli; at the default gate
probability 0.999 the difference is 1e-3 of :math:`\bar P`).

**Reporting**. :meth:`tracks` reports the Bernoullis with :math:`r \ge`
``report_threshold``, with their existence and labels. With a ``termination_threshold``
below the report threshold, reporting has the confirmation and termination of radar
trackers with track existence (JIPDA): a track is confirmed when its existence reaches the
report threshold and stays reported until it falls below the termination threshold, so a
held target's track is not dropped from the report by a few missed looks in clutter; a
terminated track is confirmed again if it climbs back (both are decided after each
predict and after each step's looks). The Bernoulli itself is kept or
pruned as before either way. **Planning** sees
:meth:`planning_tracks`: the Bernoullis with :math:`r \ge` ``planning_threshold`` (the
report threshold unless set lower), each weighted by its existence, so a track that has
faded below the report threshold can still be looked at and confirmed or dropped. Each
Bernoulli holds a single constant-velocity EKF; the known-target tracker's IMM modes are
not offered here.

**Arrays**. A look's work is batched: the quadrature of every Bernoulli at once, one
compiled pass over every (Bernoulli or cell, detection) pair for the innovations and
likelihoods (:func:`~sensorplan.tracking.pmb.bernoulli.pair_terms`), one for the weights
and one for the hypotheses the marginals leave (:mod:`sensorplan.tracking.pmb.hypotheses`),
one batch of EKF updates and one of mixtures. docs/tracking_pmb.md has the model, the
parameters and their sources, and what is approximated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..._types import BoolArray, FloatArray
from ..base import Looks, TrackSet, UndetectedReport, UpdateRecord, given_tracks
from ..ekf import predict as kalman_predict
from ..known_map import EDGE_EXITS, crossing_log_mass, map_edge_predict
from . import undetected
from . import hypotheses as hyp
from .association import AssociationMarginals, association_lbp
from .bernoulli import (Bernoullis, missed_existence, missed_look, mixture_moments, pair_terms,
                        updates)
from .map_tracker import MapModel, MapTracker, looks_in_order
from .sensing import Look

#: Smallest association weight of a miss or a new detection: the ratio form of belief
#: propagation needs both positive (a Bernoulli surely there and surely detectable, or a
#: detection that neither clutter nor an undetected target can explain, gets this).
MIN_WEIGHT = 1e-300


@dataclass(frozen=True)
class LookOutcome:
    """What one look's update did.

    Attributes
    ----------
    used : int          detections gated with at least one Bernoulli
    discarded : int     detections gated with none that started no Bernoulli (clutter)
    touched : (n,) bool the Bernoullis (present before the look) the look updated
    negative : (n,) bool  those the look could have detected (``Pbar > 0``)
    weights : (w_miss (n,), w_det (n, m), w_new (m,)) or None
        the association weights (None for a look without detections)
    marginals : AssociationMarginals or None
        their marginal association probabilities
    """

    used: int
    discarded: int
    touched: BoolArray
    negative: BoolArray
    weights: tuple[FloatArray, FloatArray, FloatArray] | None = None
    marginals: AssociationMarginals | None = None


class PMBTracker(MapTracker):
    """Track-oriented Poisson multi-Bernoulli tracker (see the module docstring).

    Parameters
    ----------
    model : MapModel
        The sensors, the motion model, the map and the undetected intensity's grid over it,
        the gate, the map's edge and the buildings. With ``map_edge = "exit"`` survival
        requires staying on the map; with ``"closed"`` a density predicted across a wall is
        reflected back in, its existence kept.
    means : (M, 4), optional
        Targets known at the start, each a Bernoulli (labels ``0..M-1``).
    covs : (M, 4, 4) or (4, 4), optional
        Their covariances (needed with ``means``).
    existence : float or (M,)
        Their existence probabilities (default 1: known to exist).
    survival_probability : float in (0, 1]
        :math:`p_S` per step, of Bernoullis and undetected targets; default 0.99.
    births : {"none", "edges", "uniform"} or (C,) array
        The birth intensity: expected births per step spread over the boundary cells, over
        every cell, or given per cell (row-major, :class:`~.undetected.Grid`).
    birth_rate : float >= 0
        Expected births per step over the map (with a named ``births``).
    background_birth_rate : float >= 0
        Expected births per step spread evenly over the map on top of ``births`` (default
        0). The filter's allowance for targets where its birth model puts none, chiefly a
        target whose track it lost: a detection anywhere can then start a track, and the
        intensity grows again where no look has been lately.
    initial_undetected : float >= 0
        Expected number of targets present but not known at the start, spread evenly over
        the cells (default 0).
    prune_threshold : float in [0, 1)
        Bernoullis below this existence are dropped; default 1e-3.
    report_threshold : float in (0, 1)
        :meth:`tracks` reports Bernoullis with at least this existence; default 0.5.
    recycle_threshold : float in [0, 1)
        0 (default): no recycling. Else Bernoullis below this existence are recycled into
        the undetected intensity instead of being dropped (module docstring); it must lie
        in ``[prune_threshold, report_threshold)``.
    planning_threshold : float in (0, 1), optional
        :meth:`planning_tracks` returns the Bernoullis with at least the smaller of this and
        ``report_threshold`` (default None: the report threshold, so planning sees the
        reported tracks only), and every reported track.
    termination_threshold : float in (0, 1]
        A confirmed track (one reported since its existence last reached
        ``report_threshold``) stays reported while its existence is at least the smaller of
        this and ``report_threshold``. Default 1: no hysteresis, a track is reported exactly
        while its existence is at least ``report_threshold``.
    edge_exit : {"outside", "crossing"}
        With ``map_edge = "exit"``, what a track near the edge loses of its existence in a
        predict: its predicted density's mass off the map (``outside``, the default), or the
        probability that a target on the map at the step's start crosses the edge during
        the step (``crossing``, :func:`~sensorplan.tracking.known_map.crossing_log_mass`).
        No effect with a closed edge.
    """

    def __init__(self, model: MapModel, *, means: FloatArray | None = None,
                 covs: FloatArray | None = None, existence: float | FloatArray = 1.0,
                 survival_probability: float = 0.99, births: str | FloatArray = "none",
                 birth_rate: float = 0.0, background_birth_rate: float = 0.0,
                 initial_undetected: float = 0.0, prune_threshold: float = 1e-3,
                 report_threshold: float = 0.5,
                 recycle_threshold: float = 0.0,
                 planning_threshold: float | None = None,
                 termination_threshold: float = 1.0, edge_exit: str = "outside") -> None:
        if not 0.0 < survival_probability <= 1.0:
            raise ValueError(f"survival_probability must be in (0, 1], got "
                             f"{survival_probability!r}")
        if not 0.0 <= prune_threshold < 1.0:
            raise ValueError(f"prune_threshold must be in [0, 1), got {prune_threshold!r}")
        if not 0.0 < report_threshold < 1.0:
            raise ValueError(f"report_threshold must be in (0, 1), got {report_threshold!r}")
        if not 0.0 <= recycle_threshold < 1.0:
            raise ValueError(f"recycle_threshold must be in [0, 1), got {recycle_threshold!r}")
        if recycle_threshold > 0.0 and not (
                prune_threshold <= recycle_threshold < report_threshold):
            raise ValueError(f"recycle_threshold must be 0 (off) or in [prune_threshold, "
                             f"report_threshold) = [{prune_threshold!r}, "
                             f"{report_threshold!r}), got {recycle_threshold!r}")
        if planning_threshold is not None and not 0.0 < planning_threshold < 1.0:
            raise ValueError(f"planning_threshold must be in (0, 1), got "
                             f"{planning_threshold!r}")
        if not 0.0 < termination_threshold <= 1.0:
            raise ValueError(f"termination_threshold must be in (0, 1], got "
                             f"{termination_threshold!r}")
        if edge_exit not in EDGE_EXITS:
            raise ValueError(f"edge_exit must be one of {EDGE_EXITS}, got {edge_exit!r}")
        if not (math.isfinite(background_birth_rate) and background_birth_rate >= 0.0):
            raise ValueError(f"background_birth_rate must be >= 0, got "
                             f"{background_birth_rate!r}")
        if not (math.isfinite(initial_undetected) and initial_undetected >= 0.0):
            raise ValueError(f"initial_undetected must be >= 0, got {initial_undetected!r}")
        super().__init__(model)
        self.survival_probability = float(survival_probability)
        self.edge_exit = edge_exit
        self.prune_threshold = float(prune_threshold)
        self.report_threshold = float(report_threshold)
        self.recycle_threshold = float(recycle_threshold)
        self.planning_threshold = (self.report_threshold if planning_threshold is None
                                   else min(float(planning_threshold), self.report_threshold))
        #: Bernoullis recycled into the undetected intensity so far, and their existence.
        self.recycled, self.recycled_mass = 0, 0.0
        if isinstance(births, str):
            self.births = undetected.birth_intensity(self.grid, births, birth_rate)
        else:
            self.births = np.array(births, dtype=float).reshape(-1)
            if self.births.shape != (self.grid.size,) or not (
                    np.all(np.isfinite(self.births)) and np.all(self.births >= 0.0)):
                raise ValueError(f"births must be {self.grid.size} expected births >= 0, "
                                 "one per cell")
        if background_birth_rate > 0.0:
            self.births = self.births + undetected.birth_intensity(
                self.grid, "uniform", background_birth_rate)
        self.undetected = np.full(self.grid.size, float(initial_undetected) / self.grid.size)
        m0, P0 = given_tracks(means, covs)
        r0 = np.array(np.broadcast_to(np.asarray(existence, dtype=float), (len(m0),)))
        if np.any((r0 < 0.0) | (r0 > 1.0)):
            raise ValueError("existence must be in [0, 1]")
        self.bern = Bernoullis(r0, m0, P0, np.arange(len(m0), dtype=np.int64))
        self.next_label = len(m0)
        self.termination_threshold = min(float(termination_threshold), self.report_threshold)
        #: The labels of the confirmed tracks (reported at the end of the last predict or
        #: update), sorted: reporting keeps them down to the termination threshold.
        self.confirmed = np.zeros(0, dtype=np.int64)
        self._confirm()

    # ---------------------------------------------------------------- the tracker protocol
    def _reported(self) -> BoolArray:
        r = self.bern.r
        reported = r >= self.report_threshold
        if self.termination_threshold < self.report_threshold and len(self.confirmed):
            kept = np.isin(self.bern.labels, self.confirmed, assume_unique=True)
            reported |= kept & (r >= self.termination_threshold)
        return reported

    def _confirm(self) -> None:
        """The tracks reported now are the confirmed ones (a track below the termination
        threshold is terminated, one at the report threshold confirmed)."""
        if self.termination_threshold < self.report_threshold:
            self.confirmed = np.sort(self.bern.labels[self._reported()])

    def tracks(self) -> TrackSet:
        """The Bernoullis with existence at least ``report_threshold`` (copies)."""
        k = self._reported()
        b = self.bern
        return TrackSet(b.means[k], b.covs[k], b.r[k], b.labels[k])

    def planning_tracks(self) -> TrackSet:
        """The Bernoullis planning sees (copies): existence at least ``planning_threshold``
        (never above the report threshold), and every reported track; planning weights each
        by its existence."""
        b = self.bern
        k = b.r >= self.planning_threshold
        if self.termination_threshold < self.planning_threshold:
            k |= self._reported()
        return TrackSet(b.means[k], b.covs[k], b.r[k], b.labels[k])

    def planning_process_noise(self) -> float | FloatArray:
        """q of the CWNA motion model the planner predicts every track with."""
        return self.process_noise

    def undetected_intensity(self) -> UndetectedReport:
        """The undetected intensity as it stands (copies): the grid's centres, the expected
        undetected targets per cell, the births per cell per step, the survival
        probability and a cell's position covariance (the grid components' position
        block)."""
        return UndetectedReport(np.array(self.grid.centres), np.array(self.undetected),
                                np.array(self.births), self.survival_probability,
                                np.array(self.grid.cov[:2, :2]))

    def predict(self) -> BoolArray:
        """Predict the Bernoullis and the undetected intensity one step.

        Returns
        -------
        (T,) bool: of the tracks reported before the predict, those the map truncated
        (only with a ``map_edge``).
        """
        b = self.bern
        reported = self._reported()
        corrected = np.zeros(len(b), dtype=bool)
        if len(b):
            start = (b.means, b.covs)
            b.means, b.covs = kalman_predict(b.means, b.covs, self.F, self.Q)
            b.r = self.survival_probability * b.r
            if self.map_edge is not None:
                m, P, applied, log_mass = map_edge_predict(b.means, b.covs, *self.world,
                                                           self.map_edge)
                if self.map_edge == "exit" and self.edge_exit == "crossing":
                    # The same tracks are truncated; what they lose is the crossing's.
                    log_mass = np.zeros(len(b))
                    log_mass[applied] = crossing_log_mass(
                        start[0][applied], start[1][applied], self.F, self.Q, *self.world)
                b.means, b.covs = m, P
                b.r = b.r * np.exp(log_mass)
                corrected = applied
        self.undetected = undetected.predict(self.undetected, self.survival_probability,
                                             self.births)
        out = corrected[reported]
        self._prune()
        self._confirm()
        return out

    def update(self, looks: Looks) -> UpdateRecord:
        """Update with one step's looks, in the given (sensor) order (see the module
        docstring); the looks' aims are not used."""
        L = len(looks.sensors)
        labels_before = self.bern.labels[self._reported()]
        T = len(labels_before)
        negative = np.zeros(T, dtype=bool)
        inflated = np.zeros(T, dtype=bool)
        used = np.zeros(L, dtype=np.int64)
        discarded = np.zeros(L, dtype=np.int64)
        for n, (look, Z) in enumerate(looks_in_order(looks)):
            present = self.bern.labels
            out = self.update_look(look, Z)
            used[n], discarded[n] = out.used, out.discarded
            if T and out.negative.any():
                # Labels ascend in both arrays: the present Bernoulli of each reported one.
                at = np.minimum(np.searchsorted(present, labels_before), len(present) - 1)
                negative |= (present[at] == labels_before) & out.negative[at]
        self._confirm()
        return UpdateRecord(negative, inflated, np.zeros(T, dtype=bool),
                            np.zeros(T, dtype=bool), used, discarded)

    # ---------------------------------------------------------------- one look
    def update_look(self, look: Look, Z: FloatArray) -> LookOutcome:
        """Update the Bernoullis and the undetected intensity with one look's detections
        ``Z (m, 2)`` (steps 1-6 of the module docstring)."""
        b, s = self.bern, self.sensing
        n, m = len(b), len(Z)
        # 1. Missed-look hypotheses.
        pbar, mm, mP = np.zeros(n), b.means, b.covs
        if n:
            seen, p, chol = s.quadrature(b.means, b.covs, look)
            if seen.size:
                m_, P_, pbar[seen] = missed_look(b.means[seen], b.covs[seen], chol, p)
                mm, mP = b.means.copy(), b.covs.copy()
                mm[seen], mP[seen] = m_, P_
        detect = s.detectable(self.grid.centres, look)                       # (C,)
        if m == 0:
            # A missed look: r' and the missed-look density.
            rows = np.flatnonzero(pbar > 0.0)
            if rows.size:
                b.r = b.r.copy()
                b.r[rows] = missed_existence(b.r[rows], pbar[rows])
                b.means, b.covs = mm, mP
            self.undetected = undetected.thin(self.undetected, detect)
            self._prune()
            return LookOutcome(0, 0, pbar > 0.0, pbar > 0.0)
        # 2. Gating: the Bernoullis and the cells the look could detect, in one batch.
        cells = np.flatnonzero((detect > 0.0) & (self.undetected > 0.0))
        means = np.concatenate([b.means, self._cell_means[cells]])
        covs = np.concatenate([b.covs, self._cell_covs[:cells.size]])
        terms = pair_terms(s, look, means, covs, Z, self.gate)
        # 3. Association weights and their marginals.
        w = hyp.weights(terms.lik, b.r, s.detection_probability(b.means[:, :2], look), pbar,
                        self.undetected[cells] * detect[cells], s.clutter(Z, look),
                        MIN_WEIGHT)
        marg = association_lbp(w.w_miss, w.w_det, w.w_new)
        # 4-5. Every hypothesis: missed (the rows the look updates), detected (gated
        # Bernoulli pairs), new (gated cells of the detections that start a Bernoulli);
        # the detected and new ones are EKF updates of one batch; each Bernoulli's mixture
        # is moment matched.
        h = hyp.hypotheses(marg.p_det, marg.p_new, w, pbar, self.prune_threshold)
        rows, started = h.rows, h.started
        xu, Pu = updates(means, covs, terms, h.unique, h.which, h.det)
        w_miss = marg.p_miss[rows] * missed_existence(b.r[rows], pbar[rows])
        total, gm, gP = mixture_moments(rows.size + started.size,
                                        (w_miss, np.arange(rows.size), mm[rows], mP[rows]),
                                        (h.weight, h.group, xu, Pu))
        # r' of the Bernoulli rows: their missed and detected hypotheses' weights. One
        # with none of positive weight has r' = 0 (pruned below) and keeps its moments.
        r_post = total[:rows.size]
        live = np.flatnonzero(r_post > 0.0)
        b.r = b.r.copy()
        b.r[rows] = np.minimum(r_post, 1.0)
        b.means, b.covs = b.means.copy(), b.covs.copy()
        b.means[rows[live]], b.covs[rows[live]] = gm[live], gP[live]
        if started.size:
            labels = np.arange(self.next_label, self.next_label + started.size, dtype=np.int64)
            self.next_label += started.size
            b.append(np.minimum(h.r_new, 1.0), gm[rows.size:], gP[rows.size:], labels)
        # 6. Thin the undetected intensity; prune.
        self.undetected = undetected.thin(self.undetected, detect)
        in_gate = int(np.count_nonzero(terms.gated[:n].any(axis=0)))
        touched = np.zeros(n, dtype=bool)
        touched[rows] = True
        outcome = LookOutcome(in_gate, m - in_gate - h.started_alone, touched, pbar > 0.0,
                              (w.w_miss, w.w_det, w.w_new), marg)
        self._prune()
        return outcome

    def _prune(self) -> None:
        """Drop the Bernoullis below ``prune_threshold``, or with recycling on, recycle
        those below ``recycle_threshold`` into the undetected intensity."""
        b = self.bern
        if self.recycle_threshold > 0.0:
            low = b.r < self.recycle_threshold
            if low.any():
                self.undetected = self.undetected + undetected.recycle(
                    self.grid, b.r[low], b.means[low, :2], b.covs[low, :2, :2])
                self.recycled += int(np.count_nonzero(low))
                self.recycled_mass += float(b.r[low].sum())
                b.keep(~low)
            return
        keep = b.r >= self.prune_threshold
        if not keep.all():
            b.keep(keep)


__all__ = ["MIN_WEIGHT", "LookOutcome", "PMBTracker"]
