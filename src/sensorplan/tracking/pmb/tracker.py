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
the model's ``process_noise``, or a given ``motion = (F, Q)``) and :math:`r \leftarrow p_S r`
(with ``established_survival``, an established Bernoulli, one whose existence has once
reached ``established_existence``, survives with that instead).
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
label). With ``recycle_motion = "moving"`` the recycled Bernoulli instead stays a Gaussian
component of :math:`D_u` that moves as the targets do, as the source keeps it: each predict
is its Kalman prediction, the survival and the map's edge; each look multiplies its weight
by :math:`1 - \bar P` and leaves it the missed-look density; a detection it gates gets its
weight :math:`w P_d l` in :math:`\lambda_u(z)` and its update in the new Bernoulli's
mixture, beside the cells'. Once its position spread exceeds a cell's side (or its weight
falls below ``prune_threshold``) it is added to the cells as above, so the components stay
few. Recycling replaces pruning: no Bernoulli is dropped, and ``prune_threshold`` only
keeps a detection from starting a Bernoulli below it; so ``recycle_threshold`` may not be
below ``prune_threshold``, nor at or above ``report_threshold`` (a reported track would
be recycled at once).

**Split hypotheses** (off by default). Step 4's merge is what makes the filter a PMB: one
Gaussian per Bernoulli, however far apart its hypotheses lie. A detection in a coasting
track's gate that is not its target's then pulls the whole track to it. With
``split_existence > 0``, a Bernoulli whose missed hypothesis and whose detected hypotheses
each hold at least that existence (:math:`p^{miss}_i r^{miss}_i` and
:math:`\sum_j p^{det}_{ij}`) becomes two Bernoullis instead: the part of larger existence
keeps the label, the other gets the next unused one, each with its own moments, and the
two existences sum to the merged :math:`r'_i`. So a track that took a stray detection
leaves a Bernoulli where the target would be had it been missed, and a later detection
there confirms it; a Poisson multi-Bernoulli mixture filter keeps the two as hypotheses of
one global mixture, this keeps them as independent Bernoullis (the expected number of
targets is the same; that at most one of them exists is lost). A split never takes a
track out of the report: when the merged existence reaches the report threshold, the
larger part must too. One motion model per Bernoulli only. No preset sets it: on the
``search`` preset it held found targets worse than the merge (docs/tracking_pmb.md).

**Mixture densities**. With ``density_components = R > 1`` a Bernoulli's density is a
mixture of up to R Gaussians instead (:mod:`sensorplan.tracking.pmb.mixture`): each
component's missed hypothesis and its detected ones are kept as candidates and reduced
back to R by the merges that lose least (Runnalls' cost), so the missed and detected
hypotheses of one target stay apart within one Bernoulli, its existence and label shared
(that at most one of them is the target is kept). The association, the report and the
planner see the components' moment-matched Gaussian; the components do not switch, each
is predicted with the one motion model. The ``search`` preset keeps two, with the
``crossing`` edge charge: there they lost held targets in fewer runs (docs/tracking_pmb.md).

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
Bernoulli holds a single constant-velocity EKF, or with ``mode_process_noise`` an
interacting multiple model mixture of CWNA modes (:mod:`sensorplan.tracking.pmb.modes`
has its predict and update); the planner then predicts each track with its effective q.

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

from ..._types import BoolArray, FloatArray, IntArray
from ..base import Looks, TrackSet, UndetectedReport, UpdateRecord, given_tracks
from ..ekf import predict as kalman_predict
from ..known_map import EDGE_EXITS, crossing_log_mass, map_edge_predict
from . import undetected
from . import hypotheses as hyp
from . import mixture
from . import modes as imm
from .association import AssociationMarginals, association_lbp
from .bernoulli import (Bernoullis, missed_existence, missed_look, mixture_moments, pair_terms,
                        updates)
from .map_tracker import MapModel, MapTracker, looks_in_order
from .sensing import Look

#: Smallest association weight of a miss or a new detection: the ratio form of belief
#: propagation needs both positive (a Bernoulli surely there and surely detectable, or a
#: detection that neither clutter nor an undetected target can explain, gets this).
MIN_WEIGHT = 1e-300
#: What a recycled Bernoulli becomes: mass on the grid where it was, or a moving component.
RECYCLE_MOTIONS = ("static", "moving")


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
    established_survival : float in (0, 1], optional
        :math:`p_S` of an established Bernoulli (one whose existence has reached
        ``established_existence`` since it was started; its label keeps the mark). None
        (the default): ``survival_probability``, whatever a Bernoulli's history. The
        generic survival does two jobs: a real target's death, and clearing Bernoullis
        that clutter started; an established one is seldom clutter, so its survival can be
        nearer the targets' own. Keep it below 1: at 1 a Bernoulli at existence 1 (a known
        target, or an update rounded to 1) cannot lose existence to missed looks.
    established_existence : float in (0, 1)
        The existence at which a Bernoulli becomes established; default 0.99.
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
    split_existence : float in [0, 0.5]
        0 (default): a Bernoulli's hypotheses are merged into one Gaussian after each look.
        Else a Bernoulli whose missed and detected hypotheses each hold at least this
        existence is split into two (module docstring); at least ``prune_threshold``, and
        one motion model per Bernoulli.
    density_components : int in [1, 8]
        The Gaussian components each Bernoulli's density keeps after a look: 1 (default)
        moment-matches its hypotheses into one Gaussian; R > 1 keeps R, each component's
        missed and detected hypotheses reduced back to R by Runnalls' merge
        (:mod:`.mixture`). One motion model per Bernoulli, and no ``split_existence``.
    recycle_motion : {"static", "moving"}
        What a recycled Bernoulli becomes: mass on the cells where it was (``static``, the
        default), or a Gaussian component of the undetected intensity that moves with the
        motion model until its position spread exceeds a cell (``moving``; needs recycling
        on and one motion model per Bernoulli). See the module docstring.
    birth_velocity : {"isotropic", "inward"}
        The velocity prior of a target first detected in a cell: mean zero and the model's
        ``velocity_var`` per axis everywhere (``isotropic``, the default), or, with
        ``edges`` births, on the map's boundary cells the velocity of a target born there
        heading inward (:func:`~.undetected.cell_velocities`, from the model's
        ``speed_range``).
    mode_process_noise : sequence of float, optional
        The q's (m^2/s^3) of an IMM's CWNA modes in every Bernoulli (None, the default: the
        model's single motion model). Not with a model's own ``motion``.
    switching : (R, R), optional
        The IMM's Markov switching matrix (rows sum to 1); needed with
        ``mode_process_noise``.
    """

    def __init__(self, model: MapModel, *, means: FloatArray | None = None,
                 covs: FloatArray | None = None, existence: float | FloatArray = 1.0,
                 survival_probability: float = 0.99,
                 established_survival: float | None = None,
                 established_existence: float = 0.99, births: str | FloatArray = "none",
                 birth_rate: float = 0.0, background_birth_rate: float = 0.0,
                 initial_undetected: float = 0.0, prune_threshold: float = 1e-3,
                 report_threshold: float = 0.5,
                 recycle_threshold: float = 0.0, recycle_motion: str = "static",
                 split_existence: float = 0.0, density_components: int = 1,
                 planning_threshold: float | None = None,
                 termination_threshold: float = 1.0, edge_exit: str = "outside",
                 birth_velocity: str = "isotropic",
                 mode_process_noise: FloatArray | tuple[float, ...] | None = None,
                 switching: FloatArray | None = None) -> None:
        if not 0.0 < survival_probability <= 1.0:
            raise ValueError(f"survival_probability must be in (0, 1], got "
                             f"{survival_probability!r}")
        if established_survival is not None and not 0.0 < established_survival <= 1.0:
            raise ValueError(f"established_survival must be in (0, 1], got "
                             f"{established_survival!r}")
        if not 0.0 < established_existence < 1.0:
            raise ValueError(f"established_existence must be in (0, 1), got "
                             f"{established_existence!r}")
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
        if recycle_motion not in RECYCLE_MOTIONS:
            raise ValueError(f"recycle_motion must be one of {RECYCLE_MOTIONS}, got "
                             f"{recycle_motion!r}")
        if recycle_motion == "moving" and (recycle_threshold == 0.0
                                           or mode_process_noise is not None):
            raise ValueError("recycle_motion 'moving' needs recycling on (recycle_threshold "
                             "> 0) and one motion model per Bernoulli (no "
                             "mode_process_noise)")
        if not (0.0 <= split_existence <= 0.5 and (
                split_existence == 0.0 or split_existence >= prune_threshold)):
            raise ValueError(f"split_existence must be 0 (off) or in [prune_threshold "
                             f"({prune_threshold!r}), 0.5], got {split_existence!r}")
        if split_existence > 0.0 and mode_process_noise is not None:
            raise ValueError("split_existence needs one motion model per Bernoulli (no "
                             "mode_process_noise)")
        if not (isinstance(density_components, (int, np.integer))
                and 1 <= density_components <= mixture.MAX_COMPONENTS):
            raise ValueError(f"density_components must be an integer in [1, "
                             f"{mixture.MAX_COMPONENTS}], got {density_components!r}")
        if density_components > 1 and (mode_process_noise is not None
                                       or split_existence > 0.0
                                       or recycle_motion == "moving"):
            raise ValueError("density_components > 1 needs one motion model per Bernoulli "
                             "(no mode_process_noise), split_existence 0 and "
                             "recycle_motion 'static'")
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
        if (mode_process_noise is None) != (switching is None):
            given = "switching" if mode_process_noise is None else "mode_process_noise"
            raise ValueError(f"mode_process_noise and switching go together (an IMM), got "
                             f"only {given}")
        if birth_velocity not in undetected.BIRTH_VELOCITIES:
            raise ValueError(f"birth_velocity must be one of {undetected.BIRTH_VELOCITIES}, "
                             f"got {birth_velocity!r}")
        edges = isinstance(births, str) and births == "edges"
        if birth_velocity == "inward" and not (edges and model.speed_range is not None):
            raise ValueError("birth_velocity 'inward' needs births = 'edges' and the model's "
                             f"speed_range, got births {births!r} and speed_range "
                             f"{model.speed_range!r}")
        if mode_process_noise is not None and model.motion is not None:
            raise ValueError("mode_process_noise must be None with a model's own motion "
                             "(the IMM's modes are CWNA models)")
        super().__init__(model)
        #: The IMM's modes (None: one motion model).
        self.modes = (None if mode_process_noise is None
                      else imm.make_modes(self.dt, mode_process_noise, switching))
        #: Components of every Bernoulli's density (> 1: a mixture carried as modes that
        #: do not switch, :mod:`.mixture`).
        self.density_components = int(density_components)
        if self.density_components > 1:
            self.modes = mixture.components_as_modes(self.process_noise, self.Q,
                                                     self.density_components)
        self.birth_velocity = birth_velocity
        if birth_velocity == "inward":
            assert model.speed_range is not None
            v_mean, v_cov = undetected.cell_velocities(self.grid, model.speed_range)
            self._cell_means = np.array(self._cell_means)
            self._cell_covs = np.array(self._cell_covs)
            self._cell_means[:, 2:], self._cell_covs[:, 2:, 2:] = v_mean, v_cov
        # What the edge's crossing probability predicts with: each mode's Q, or the one.
        self._edge_Q = [self.Q] if self.modes is None else list(self.modes.Q)
        self.survival_probability = float(survival_probability)
        self.established_survival = (None if established_survival is None
                                     else float(established_survival))
        self.established_existence = float(established_existence)
        self.edge_exit = edge_exit
        self.prune_threshold = float(prune_threshold)
        self.report_threshold = float(report_threshold)
        self.recycle_threshold = float(recycle_threshold)
        self.split_existence = float(split_existence)
        #: Bernoullis split in two so far.
        self.splits = 0
        self.planning_threshold = (self.report_threshold if planning_threshold is None
                                   else min(float(planning_threshold), self.report_threshold))
        #: Bernoullis recycled into the undetected intensity so far, and their existence.
        self.recycled, self.recycled_mass = 0, 0.0
        self.recycle_motion = recycle_motion
        #: The moving components of the undetected intensity: weights (K,), means (K, 4)
        #: and covariances (K, 4, 4) (``recycle_motion = "moving"``).
        self.moving_weights = np.zeros(0)
        self.moving_means = np.zeros((0, 4))
        self.moving_covs = np.zeros((0, 4, 4))
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
        if self.modes is not None:
            imm.start_modes(self.bern, self.modes)
        self.next_label = len(m0)
        self.termination_threshold = min(float(termination_threshold), self.report_threshold)
        #: The labels of the confirmed tracks (reported at the end of the last predict or
        #: update), sorted: reporting keeps them down to the termination threshold.
        self.confirmed = np.zeros(0, dtype=np.int64)
        #: The labels of the established Bernoullis present, sorted.
        self.established = np.zeros(0, dtype=np.int64)
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
        threshold is terminated, one at the report threshold confirmed); a Bernoulli at
        the established existence is established from now on."""
        if self.termination_threshold < self.report_threshold:
            self.confirmed = np.sort(self.bern.labels[self._reported()])
        if self.established_survival is not None:
            b = self.bern
            known = np.isin(b.labels, self.established, assume_unique=True)
            self.established = b.labels[known | (b.r >= self.established_existence)]

    def _survival(self) -> float | FloatArray:
        """:math:`p_S` of every Bernoulli, ``(B,)``, or one for all."""
        if self.established_survival is None:
            return self.survival_probability
        held = np.isin(self.bern.labels, self.established, assume_unique=True)
        return np.where(held, self.established_survival, self.survival_probability)

    def tracks(self) -> TrackSet:
        """The Bernoullis with existence at least ``report_threshold`` (copies)."""
        k = self._reported()
        b = self.bern
        return TrackSet(b.means[k], b.covs[k], b.r[k], b.labels[k])

    def _planned(self) -> BoolArray:
        k = self.bern.r >= self.planning_threshold
        if self.termination_threshold < self.planning_threshold:
            k |= self._reported()
        return k

    def planning_tracks(self) -> TrackSet:
        """The Bernoullis planning sees (copies): existence at least ``planning_threshold``
        (never above the report threshold), and every reported track; planning weights each
        by its existence."""
        b, k = self.bern, self._planned()
        return TrackSet(b.means[k], b.covs[k], b.r[k], b.labels[k])

    def planning_process_noise(self) -> float | FloatArray:
        """q of the CWNA motion model the planner predicts every track with: the model's
        (mixture densities included: their components share it), or with IMM modes each
        planning track's effective q one step ahead, ``(mu Pi) . q`` (one per
        :meth:`planning_tracks` row)."""
        if self.modes is None or self.density_components > 1:
            return self.process_noise
        assert self.bern.mode_probs is not None
        return imm.planning_noise(self.bern.mode_probs[self._planned()], self.modes)

    def undetected_intensity(self) -> UndetectedReport:
        """The undetected intensity as it stands (copies): the grid's centres, the expected
        undetected targets per cell, the births per cell per step, the survival
        probability and a cell's position covariance (the grid components' position
        block)."""
        return UndetectedReport(np.array(self.grid.centres), self.undetected_cells(),
                                np.array(self.births), self.survival_probability,
                                np.array(self.grid.cov[:2, :2]))

    def undetected_cells(self) -> FloatArray:
        """The expected undetected targets per cell ``(C,)`` (a copy), the moving components
        added by their position marginals' mass in each cell."""
        if not self.moving_weights.size:
            return np.array(self.undetected)
        return self.undetected + undetected.recycle(
            self.grid, self.moving_weights, self.moving_means[:, :2],
            self.moving_covs[:, :2, :2])

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
        if len(b) and self.modes is not None:
            corrected = self._predict_modes()
        elif len(b):
            b.means, b.covs, b.r, corrected = self._predict_gaussians(
                b.means, b.covs, self._survival() * b.r)
        self.undetected = undetected.predict(self.undetected, self.survival_probability,
                                             self.births)
        self._predict_moving()
        out = corrected[reported]
        self._prune()
        self._confirm()
        return out

    def _predict_gaussians(self, means: FloatArray, covs: FloatArray, weights: FloatArray
                           ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        """One motion model's predict of densities ``(B, 4)``, ``(B, 4, 4)`` whose weights
        (existence or expected number, survival applied) the map's edge then charges: the
        new moments, weights, and which the edge changed."""
        m, P = kalman_predict(means, covs, self.F, self.Q)
        if self.map_edge is None:
            return m, P, weights, np.zeros(len(means), dtype=bool)
        m, P, applied, log_mass = self._at_edge(m, P, means, covs)
        return m, P, weights * np.exp(log_mass), applied

    def _predict_moving(self) -> None:
        """The moving components' predict (as a Bernoulli's), then those spread over more
        than a cell, or below the pruning threshold, added to the cells."""
        if not self.moving_weights.size:
            return
        m, P, w, _ = self._predict_gaussians(self.moving_means, self.moving_covs,
                                             self.survival_probability * self.moving_weights)
        side = min(self.grid.width / self.grid.nx, self.grid.height / self.grid.ny)
        spread = np.sqrt(np.maximum(P[:, 0, 0], P[:, 1, 1]))
        settle = (spread > side) | (w < self.prune_threshold)
        if settle.any():
            self.undetected = self.undetected + undetected.recycle(
                self.grid, w[settle], m[settle, :2], P[settle, :2, :2])
        keep = ~settle
        self.moving_weights, self.moving_means, self.moving_covs = w[keep], m[keep], P[keep]

    def _thin_moving(self, look: Look) -> None:
        """A look's thinning of the moving components: weight times ``1 - Pbar``, and the
        missed-look density."""
        if self.moving_weights.size:
            pbar, mm, mP = self._missed(self.moving_means, self.moving_covs, look)
            self.moving_weights = self.moving_weights * (1.0 - pbar)
            self.moving_means, self.moving_covs = mm, mP

    def _at_edge(self, means: FloatArray, covs: FloatArray, start_means: FloatArray,
                 start_covs: FloatArray, mode: IntArray | None = None
                 ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]:
        """The map's edge on predicted densities ``(B, 4)``, ``(B, 4, 4)`` that started the
        step at ``start_*``: their new moments, which were changed, and the log of what
        each keeps of its existence (``mode (B,)``: each one's IMM mode, None: one
        model)."""
        assert self.map_edge is not None
        m, P, applied, log_mass = map_edge_predict(means, covs, *self.world, self.map_edge)
        if self.map_edge == "exit" and self.edge_exit == "crossing":
            # The same tracks are truncated; what they lose is the crossing's.
            log_mass = np.zeros(len(means))
            for j, Q in enumerate(self._edge_Q):
                rows = applied if mode is None else applied & (mode == j)
                log_mass[rows] = crossing_log_mass(start_means[rows], start_covs[rows],
                                                   self.F, Q, *self.world)
        return m, P, applied, log_mass

    def _predict_modes(self) -> BoolArray:
        """The IMM predict of every Bernoulli (:func:`.modes.predict`; a mixture density's
        components each on their own, :func:`.mixture.predict`), its map edge per mode or
        component; returns which Bernoullis the edge changed."""
        b, modes = self.bern, self.modes
        assert modes is not None
        n, R = len(b), len(modes.q)
        x0, P0, xp, Pp = (imm.predict(b, self.F, modes) if self.density_components == 1
                          else mixture.predict(b, self.F, self.Q))
        b.r = self._survival() * b.r
        corrected = np.zeros(n, dtype=bool)
        if self.map_edge is not None:
            m, P, applied, log_mass = self._at_edge(
                xp.reshape(-1, 4), Pp.reshape(-1, 4, 4), x0.reshape(-1, 4),
                P0.reshape(-1, 4, 4), np.tile(np.arange(R), n))
            b.mode_means, b.mode_covs = m.reshape(n, R, 4), P.reshape(n, R, 4, 4)
            imm.keep_on_map(b, log_mass.reshape(n, R))
            corrected = np.asarray(applied.reshape(n, R).any(axis=1))
        imm.combine(b)
        return corrected

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
        if self.modes is not None:
            return self._update_look_modes(look, Z)
        b, s = self.bern, self.sensing
        n, m = len(b), len(Z)
        # 1. Missed-look hypotheses.
        pbar, mm, mP = self._missed(b.means, b.covs, look)
        detect = s.detectable(self.grid.centres, look)                       # (C,)
        if m == 0:
            # A missed look: r' and the missed-look density.
            rows = np.flatnonzero(pbar > 0.0)
            if rows.size:
                b.r = b.r.copy()
                b.r[rows] = missed_existence(b.r[rows], pbar[rows])
                b.means, b.covs = mm, mP
            self.undetected = undetected.thin(self.undetected, detect)
            self._thin_moving(look)
            self._prune()
            return LookOutcome(0, 0, pbar > 0.0, pbar > 0.0)
        # 2. Gating: the Bernoullis, the cells the look could detect and the moving
        # components it could (after the cells: the undetected intensity's rows), in one
        # batch.
        cells = np.flatnonzero((detect > 0.0) & (self.undetected > 0.0))
        moving = (s.detectable(self.moving_means[:, :2], look) * self.moving_weights
                  if self.moving_weights.size else np.zeros(0))
        comps = np.flatnonzero(moving > 0.0)
        means = np.concatenate([b.means, self._cell_means[cells], self.moving_means[comps]])
        covs = np.concatenate([b.covs, self._cell_covs[cells], self.moving_covs[comps]])
        terms = pair_terms(s, look, means, covs, Z, self.gate)
        # 3. Association weights and their marginals.
        w = hyp.weights(terms.lik, b.r, s.detection_probability(b.means[:, :2], look), pbar,
                        np.concatenate([self.undetected[cells] * detect[cells],
                                        moving[comps]]),
                        s.clutter(Z, look), MIN_WEIGHT)
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
        split = (self._split(w_miss, h, xu, Pu, (r_post, gm[:rows.size], gP[:rows.size]),
                             mm[rows], mP[rows])
                 if self.split_existence > 0.0 else None)
        if split is not None:
            r_post, gm[:rows.size], gP[:rows.size] = split[0], split[1], split[2]
        live = np.flatnonzero(r_post > 0.0)
        b.r = b.r.copy()
        b.r[rows] = np.minimum(r_post, 1.0)
        b.means, b.covs = b.means.copy(), b.covs.copy()
        b.means[rows[live]], b.covs[rows[live]] = gm[live], gP[live]
        self._start(h, gm[rows.size:], gP[rows.size:])
        if split is not None and len(split[3]):
            labels = np.arange(self.next_label, self.next_label + len(split[3]),
                               dtype=np.int64)
            self.next_label += len(labels)
            b.append(np.minimum(split[3], 1.0), split[4], split[5], labels)
            self.splits += len(labels)
        self._thin_moving(look)
        return self._finish_look(detect, terms.gated[:n], n, h, pbar, w, marg)

    def _split(self, w_miss: FloatArray, h: hyp.Hypotheses, xu: FloatArray, Pu: FloatArray,
               merged: tuple[FloatArray, FloatArray, FloatArray], miss_means: FloatArray,
               miss_covs: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray,
                                               FloatArray, FloatArray, FloatArray]:
        """Split the look's updated rows (module docstring): given each row's missed
        hypothesis (weight ``w_miss (q,)``, moments) and its merged existence and moments
        ``merged``, the rows with a split one as its larger part, and the smaller parts to
        append: ``(r (q,), means (q, 4), covs (q, 4, 4), r_new (k,), means_new (k, 4),
        covs_new (k, 4, 4))``."""
        q = len(w_miss)
        det = h.group < q
        d_tot, dm, dP = mixture_moments(q, (h.weight[det], h.group[det], xu[det], Pu[det]))
        low, high = np.minimum(w_miss, d_tot), np.maximum(w_miss, d_tot)
        split = (low >= self.split_existence) & (
            (merged[0] < self.report_threshold) | (high >= self.report_threshold))
        rows = np.flatnonzero(split)
        det_first = d_tot[rows] >= w_miss[rows]
        keep = (np.where(det_first[:, None], dm[rows], miss_means[rows]),
                np.where(det_first[:, None, None], dP[rows], miss_covs[rows]))
        other = (np.where(det_first[:, None], miss_means[rows], dm[rows]),
                 np.where(det_first[:, None, None], miss_covs[rows], dP[rows]))
        r, gm, gP = merged[0].copy(), merged[1].copy(), merged[2].copy()
        r[rows], gm[rows], gP[rows] = high[rows], keep[0], keep[1]
        return r, gm, gP, low[rows], other[0], other[1]

    def _missed(self, means: FloatArray, covs: FloatArray, look: Look,
                among: BoolArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The missed-look hypotheses of densities ``(B, 4)``, ``(B, 4, 4)`` (step 1):
        ``Pbar (B,)`` and the densities a miss leaves (the given arrays where the look
        cannot see any). With ``among (B,)`` only those densities are updated (the others
        get Pbar 0 and keep their moments)."""
        pbar, mm, mP = np.zeros(len(means)), means, covs
        rows = None if among is None else np.flatnonzero(among)
        sub = (means, covs) if rows is None else (means[rows], covs[rows])
        if len(sub[0]):
            seen, p, chol = self.sensing.quadrature(*sub, look)
            if rows is not None:
                seen = rows[seen]
            if seen.size:
                m_, P_, pbar[seen] = missed_look(means[seen], covs[seen], chol, p)
                mm, mP = means.copy(), covs.copy()
                mm[seen], mP[seen] = m_, P_
        return pbar, mm, mP

    def _start(self, h: hyp.Hypotheses, means: FloatArray, covs: FloatArray) -> None:
        """Append the Bernoullis the look's detections start (step 5), each with the next
        unused label."""
        k = h.started.size
        if k:
            labels = np.arange(self.next_label, self.next_label + k, dtype=np.int64)
            self.next_label += k
            self.bern.append(np.minimum(h.r_new, 1.0), means, covs, labels,
                             None if self.modes is None else self.modes.initial)

    def _finish_look(self, detect: FloatArray, gated: BoolArray, n: int, h: hyp.Hypotheses,
                     pbar: FloatArray, w: hyp.Weights, marg: AssociationMarginals
                     ) -> LookOutcome:
        """Step 6 (thin the undetected intensity, prune) and the look's outcome; ``gated``
        the (Bernoulli or mode, detection) pairs in a gate."""
        self.undetected = undetected.thin(self.undetected, detect)
        m = gated.shape[1]
        in_gate = int(np.count_nonzero(gated.any(axis=0)))
        touched = np.zeros(n, dtype=bool)
        touched[h.rows] = True
        outcome = LookOutcome(in_gate, m - in_gate - h.started_alone, touched, pbar > 0.0,
                              (w.w_miss, w.w_det, w.w_new), marg)
        self._prune()
        return outcome

    def _update_look_modes(self, look: Look, Z: FloatArray) -> LookOutcome:
        """:meth:`update_look` with IMM modes in every Bernoulli (:mod:`.modes`), or with
        mixture densities (:mod:`.mixture`: each component's missed and detected hypotheses
        kept apart, then reduced)."""
        b, s, modes = self.bern, self.sensing, self.modes
        assert modes is not None and b.mode_probs is not None
        assert b.mode_means is not None and b.mode_covs is not None
        n, m, R = len(b), len(Z), len(modes.q)
        cm, cP = b.mode_means.reshape(-1, 4), b.mode_covs.reshape(-1, 4, 4)
        # 1. Each mode's missed-look hypothesis; the Bernoulli's Pbar mixes them. A
        # mixture's component of weight 0 is a placeholder that no hypothesis reaches.
        pbar_c, mm, mP = self._missed(cm, cP, look,
                                      None if self.density_components == 1
                                      else b.mode_probs.reshape(-1) > 0.0)
        pbar_modes = pbar_c.reshape(n, R)
        pbar = imm.bernoulli_pbar(b.mode_probs, pbar_modes)
        detect = s.detectable(self.grid.centres, look)
        if m == 0:
            rows = np.flatnonzero(pbar > 0.0)
            if rows.size:
                b.r = b.r.copy()
                b.r[rows] = missed_existence(b.r[rows], pbar[rows])
                probs = b.mode_probs.copy()
                probs[rows] = imm.missed_probs(b.mode_probs[rows], pbar_modes[rows])
                b.mode_probs = probs
                b.mode_means, b.mode_covs = mm.reshape(n, R, 4), mP.reshape(n, R, 4, 4)
                imm.combine(b, rows)
            self.undetected = undetected.thin(self.undetected, detect)
            self._prune()
            return LookOutcome(0, 0, pbar > 0.0, pbar > 0.0)
        # 2. Gating: every mode of every Bernoulli, and the cells, in one batch.
        cells = np.flatnonzero((detect > 0.0) & (self.undetected > 0.0))
        means = np.concatenate([cm, self._cell_means[cells]])
        covs = np.concatenate([cP, self._cell_covs[cells]])
        terms = pair_terms(s, look, means, covs, Z, self.gate)
        # 3. The Bernoullis' likelihoods mix their modes'; association as with one model.
        lik_modes = terms.lik[:n * R].reshape(n, R, m)
        lik_b = np.einsum("nr,nrm->nm", b.mode_probs, lik_modes)
        w = hyp.weights(np.concatenate([lik_b, terms.lik[n * R:]]), b.r,
                        s.detection_probability(b.means[:, :2], look), pbar,
                        self.undetected[cells] * detect[cells], s.clutter(Z, look),
                        MIN_WEIGHT)
        marg = association_lbp(w.w_miss, w.w_det, w.w_new)
        # 4-5. The hypotheses split over the modes; each mode's mixture moment matched.
        h = hyp.hypotheses(marg.p_det, marg.p_new, w, pbar, self.prune_threshold)
        mh = imm.mode_hypotheses(h, lik_modes, b.mode_probs, lik_b, n)
        rows, q = h.rows, h.rows.size
        xu, Pu = updates(means, covs, terms, mh.unique, mh.which, mh.det)
        w_miss = imm.missed_weights(marg.p_miss[rows], b.r[rows], pbar[rows],
                                    b.mode_probs[rows], pbar_modes[rows])
        comps = (rows[:, None] * R + np.arange(R)).reshape(-1)
        # Each mode's missed and detected hypotheses merge into that mode; a mixture's
        # are 2R candidates per Bernoulli, reduced back to R.
        G, miss_groups, det_groups = R, np.arange(q * R), mh.group
        if self.density_components > 1:
            G = 2 * R
            miss_groups = mixture.missed_groups(q, R)
            det_groups = mixture.detected_groups(mh.group, q, R)
        total, gm, gP = mixture_moments(q * G + h.started.size,
                                        (w_miss.reshape(-1), miss_groups, mm[comps],
                                         mP[comps]),
                                        (mh.weight, det_groups, xu, Pu))
        merged = (total[:q * G].reshape(q, G), gm[:q * G].reshape(q, G, 4),
                  gP[:q * G].reshape(q, G, 4, 4))
        if G > R:
            merged = mixture.reduce(*merged, R)
        r_post, live = imm.merged_modes(b, rows, *merged)
        b.r = b.r.copy()
        b.r[rows] = np.minimum(r_post, 1.0)
        imm.combine(b, rows[live])
        self._start(h, gm[q * G:], gP[q * G:])
        return self._finish_look(detect, terms.gated[:n * R], n, h, pbar, w, marg)

    def _prune(self) -> None:
        """Drop the Bernoullis below ``prune_threshold``, or with recycling on, recycle
        those below ``recycle_threshold`` into the undetected intensity."""
        b = self.bern
        if self.recycle_threshold > 0.0:
            low = b.r < self.recycle_threshold
            if low.any():
                if self.recycle_motion == "moving":
                    self.moving_weights = np.concatenate([self.moving_weights, b.r[low]])
                    self.moving_means = np.concatenate([self.moving_means, b.means[low]])
                    self.moving_covs = np.concatenate([self.moving_covs, b.covs[low]])
                else:
                    self.undetected = self.undetected + undetected.recycle(
                        self.grid, b.r[low], b.means[low, :2], b.covs[low, :2, :2])
                self.recycled += int(np.count_nonzero(low))
                self.recycled_mass += float(b.r[low].sum())
                b.keep(~low)
            return
        keep = b.r >= self.prune_threshold
        if not keep.all():
            b.keep(keep)


__all__ = ["MIN_WEIGHT", "RECYCLE_MOTIONS", "LookOutcome", "PMBTracker"]
