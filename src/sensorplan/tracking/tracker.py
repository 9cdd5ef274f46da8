r"""The tracker of known targets: one filter per target, and the options that keep its
tracks honest.

It is the tracker of the paper's configuration (``tracker.kind = "known"``): the number of
targets is known, and a look pointed at target ``j`` can only detect ``j``, so track ``j``
is target ``j`` (its label is ``j``, its existence 1). It follows the tracker protocol of
:mod:`sensorplan.tracking.base`.

Each target has a Gaussian track, the moment-matched state of its filter: a single extended
Kalman filter with a CWNA motion model (``model = "cv"``) or an interacting multiple model
filter over R CWNA modes that differ in their process noise (``model = "imm"``, Blom and
Bar-Shalom 1988). The options, each switchable:

- **IMM** (R modes, Markov switching matrix :math:`\Pi`, :math:`\Pi_{ij} = P(j \mid i)`).
  Every step: mixing :math:`\bar c_j = \sum_i \Pi_{ij}\mu_i`,
  :math:`\mu_{i|j} = \Pi_{ij}\mu_i/\bar c_j`, mixed initial conditions per mode, the
  mode-matched CWNA predictions, :math:`\mu \leftarrow \bar c`; every piece of evidence
  (a measurement, a missed look, the map) then updates each mode and multiplies its
  probability by the mode's likelihood of that evidence. The combined (moment-matched)
  Gaussian is the track: what the NEES, the gate and the planner see.
- **Validation gate.** A detection is used only if the squared Mahalanobis distance of its
  innovation under the combined track, :math:`\nu^T S^{-1} \nu` with
  :math:`S = H' C H'^T + R`, is below the chi-square(2) quantile of ``gate_probability``,
  :math:`\gamma = -2\ln(1 - P_G)` (13.82 for 0.999).
- **Re-acquisition.** With the gate on and no false alarms, a detection from a look at
  target j is target j: if it falls outside the gate the track is wrong, and is restarted
  from the detection: position at the inverse measurement with its linearised covariance
  :math:`J R J^T` (:func:`sensorplan.models.radar.inverse`), velocity mean zero with the initial
  velocity variances, no cross-covariance, IMM mode probabilities at their initial values.
- **The known map** (:mod:`sensorplan.tracking.known_map`): after the predict and after the updates,
  every mode whose mean or 3-sigma box leaves the map is truncated to the map, and (known
  buildings) every mode whose 3-sigma box reaches into a building is restricted to the
  outside of the footprints: no target is ever inside one, and a look can never show that
  it is not there (a building hides its own footprint from every sensor).
- **Missed looks** (:mod:`sensorplan.tracking.missed`): a look that missed applies its negative
  information to every mode; an IMM mode's likelihood of the miss is the probability mass it
  puts outside the sensing region.
- **Lost targets** (:mod:`sensorplan.tracking.lost`): a track under which the probability of
  its run of misses since its last detection falls below ``lost_probability`` becomes a
  point-mass density on a grid (replayed from its last detection), thinned by every missed
  look and reported by its moments, until a detection re-initialises its Gaussian.

With every option off (one mode, no gate, no map) the tracker is the plain EKF.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._types import BoolArray, FloatArray, IntArray
from ..models.radar import inverse_looks
from ..models.sensors import CLUTTER_RATE, SWERLING
from .association import ASSOCIATIONS, GATE_DOF, gate_threshold, pda_update
from .base import Looks, TrackSet, UpdateRecord
from .ekf import innovations, mahalanobis2, position_update, update, update_rounds
from .imm import ModeMixture, stationary
from .known_map import building_constraint, map_constraint, map_reflection
from .lost import LostGrid, MissLog

__all__ = ["ASSOCIATIONS", "KnownTargetTracker", "LookResults", "SetResults", "gate_threshold",
           "stationary"]


@dataclass(frozen=True)
class SetResults:
    """What :meth:`KnownTargetTracker.update_sets` did with each of L looks.

    Attributes
    ----------
    used : (L,) int         detections applied to the track
    discarded : (L,) int    detections outside the gate (not used)
    restarted : (L,) bool   the track was restarted from the look's detection
    negative : (M,) bool    tracks that got a negative update (no gated detection)
    map_corrected : (M,) bool
    """

    used: IntArray
    discarded: IntArray
    restarted: BoolArray
    negative: BoolArray
    map_corrected: BoolArray


@dataclass(frozen=True)
class LookResults:
    """What :meth:`KnownTargetTracker.update_detections` did with each of L detections.

    Attributes
    ----------
    used : (L,) bool         applied to its track
    gated_out : (L,) bool    outside the gate (discarded, or used to restart)
    restarted : (L,) bool    its track was restarted from it
    map_corrected : (M,) bool  tracks the map constraint corrected after the updates
    """

    used: BoolArray
    gated_out: BoolArray
    restarted: BoolArray
    map_corrected: BoolArray


class KnownTargetTracker(ModeMixture):
    """Every known target's track, with the honest-tracking options (see the module
    docstring).

    Parameters
    ----------
    means : (M, 4)
    covs : (M, 4, 4) or (4, 4) (broadcast to every target)
    dt : float                   step (s)
    table : (N, C)               radar table of the sensors, by row
    process_noise : float        q of the single-model filter (m^2/s^3)
    mode_process_noise : sequence of float, optional
        The IMM modes' q (m^2/s^3); None: the single-model filter.
    switching : (R, R), optional
        Markov switching matrix of the modes (rows sum to 1).
    gate_probability : float in (0, 1), optional
        Validation gate; None: every detection is used.
    reacquire : bool
        Restart a track from a detection outside the gate (needs the gate; only for sensors
        without false alarms).
    association : {"pda", "nearest"}
        How the detections of a look with false alarms update the track.
    world : (width, height), optional
        The map ``[0, W] x [0, H]`` the targets never leave; None: not used.
    buildings : (K, 5), optional
        Buildings ``x0, y0, x1, y1, height`` that can hide targets: a missed look learns
        nothing about the places they hide.
    known_buildings : bool
        Restrict the tracks to the outside of the buildings' footprints after every
        predict and update (targets never enter a building); needs ``buildings``.
    reflect_walls : bool
        After every predict, reflect the part of each track that left the map off its walls
        (as the targets are) before the map's truncation; needs ``world``.
    restart_velocity_var : (2,)
        Velocity variances (m^2/s^2) of a restarted track.
    miss_update : callable, optional
        The missed-look update :meth:`update` applies to a look that returned no detection
        (:func:`sensorplan.tracking.missed.miss_update`); None: a miss changes nothing.
    detects_all : bool
        A look returns every target in view, not only the one it points at: a look's
        detections are then associated with its target's track (the nearest gated one
        without false alarms, PDA with them).
    lost_grid : LostGrid, optional
        The grid of the lost-target mode (:func:`sensorplan.tracking.lost.make_lost_grid`);
        None: the mode is off. Needs the missed-look update and ideal detection (every look
        detects its target in view, no false alarms).
    lost_probability : float in (0, 1)
        A track whose run of misses since its last detection had a probability below this
        under the track is lost.
    """

    def __init__(self, means: FloatArray, covs: FloatArray, dt: float, table: FloatArray, *,
                 process_noise: float, mode_process_noise: tuple[float, ...] | None = None,
                 switching: FloatArray | None = None, gate_probability: float | None = None,
                 reacquire: bool = False, association: str = "pda",
                 world: tuple[float, float] | None = None,
                 buildings: FloatArray | None = None, known_buildings: bool = False,
                 reflect_walls: bool = False,
                 restart_velocity_var: tuple[float, float] = (4.0, 4.0),
                 miss_update: Callable[..., Any] | None = None,
                 detects_all: bool = False, lost_grid: LostGrid | None = None,
                 lost_probability: float = 0.01) -> None:
        super().__init__(means, covs, dt, process_noise=process_noise,
                         mode_process_noise=mode_process_noise, switching=switching)
        self.table = np.ascontiguousarray(table, dtype=float)
        self.gate = None if gate_probability is None else gate_threshold(gate_probability)
        self.gate_probability = gate_probability
        if association not in ASSOCIATIONS:
            raise ValueError(f"association must be one of {ASSOCIATIONS}, got {association!r}")
        self.association = association
        if reacquire and self.gate is None:
            raise ValueError("re-acquisition needs the validation gate")
        self.reacquire = reacquire
        self.world = world
        self.buildings = None if buildings is None or len(buildings) == 0 else np.asarray(
            buildings, dtype=float).reshape(-1, 5)
        self.known_buildings = bool(known_buildings) and self.buildings is not None
        self.reflect_walls = bool(reflect_walls) and world is not None
        self.restart_velocity_var = np.asarray(restart_velocity_var, dtype=float)
        self.miss_update = miss_update
        # A look at target j returns j's detection only, when no sensor misses a target in
        # view or reports false alarms and a look detects only its target: detections then
        # update as one batch.
        self.detects_all = detects_all
        self.imperfect = bool(self.table[:, SWERLING].any() or self.table[:, CLUTTER_RATE].any()
                              or detects_all)
        self.lost_grid = lost_grid
        if lost_grid is not None:
            if self.imperfect:
                raise ValueError("the lost-target mode needs ideal detection (no false "
                                 "alarms, every look detects its target in view)")
            if not 0.0 < lost_probability < 1.0:
                raise ValueError(f"lost_probability must be in (0, 1), got {lost_probability!r}")
            M = len(self.means)
            self.log_lost = math.log(lost_probability)
            self.lost = np.zeros(M, dtype=bool)
            self.log_run = np.zeros(M)                 # log P(misses since the anchor)
            self.since = np.zeros(M, dtype=np.int64)   # steps since the anchor
            self.anchor_means = self.means.copy()
            self.anchor_covs = self.covs.copy()
            self.miss_logs = [MissLog.empty() for _ in range(M)]
            self.lost_weights: dict[int, FloatArray] = {}

    # ---------------------------------------------------------------- the tracker protocol
    def tracks(self) -> TrackSet:
        """Every target's track, labelled with the target's index (arrays held by the
        tracker: valid until its next predict or update)."""
        M = len(self.means)
        return TrackSet(self.means, self.covs, np.ones(M), self._all_rows)

    def update(self, looks: Looks) -> UpdateRecord:
        """Update with one step's looks, each aimed at a target (``looks.aims``).

        First the looks that returned nothing get the missed-look update (in sensor order,
        if the tracker has one); then the detections: with ideal detection each look's one
        detection is its target's and they apply as one batch (:meth:`update_detections`),
        else look by look with association in clutter (:meth:`update_sets`).
        """
        M, L = len(self.means), len(looks.sensors)
        sensors, aims = np.asarray(looks.sensors), np.asarray(looks.aims)
        pos, head = np.asarray(looks.positions), np.asarray(looks.headings)
        # a look aimed at no target (its detections are no target's in particular) is not
        # this tracker's to use
        counts = np.where(aims >= 0, looks.counts, -1)
        negative, inflated = np.zeros(M, dtype=bool), np.zeros(M, dtype=bool)
        restarted, corrected = np.zeros(M, dtype=bool), np.zeros(M, dtype=bool)
        used, discarded = np.zeros(L, dtype=np.int64), np.zeros(L, dtype=np.int64)
        gated_out = np.zeros(L, dtype=bool)
        empty = np.flatnonzero(counts == 0)
        if self.lost_grid is not None:
            negative, inflated = self._lost_misses(empty, sensors, aims, pos, head)
        elif self.miss_update is not None and empty.size:
            negative, inflated = self.miss(sensors[empty], aims[empty], pos[empty],
                                           head[empty], kernel=self.miss_update)
        i = np.flatnonzero(counts > 0)
        if self.lost_grid is not None and i.size:
            i = self._lost_detections(i, sensors, aims, pos, head, looks, used, restarted)
        if i.size and self.imperfect:
            res = self.update_sets(sensors[i], aims[i], [looks.detections[n] for n in i],
                                   pos[i], head[i], kernel=self.miss_update)
            negative |= res.negative
            restarted[aims[i][res.restarted]] = True
            corrected |= res.map_corrected
            used[i], discarded[i] = res.used, res.discarded
        elif i.size:
            z = np.concatenate([looks.detections[n][:1] for n in i])
            one = self.update_detections(sensors[i], aims[i], z, pos[i], head[i])
            gated_out[i] = one.gated_out
            restarted[aims[i][one.restarted]] = True
            corrected |= one.map_corrected
            used[i], discarded[i] = one.used, one.gated_out
        # A missed look has conditioned on the footprints already (jointly with the miss);
        # a detection can move a track into a building.
        if i.size:
            corrected |= self.apply_buildings(targets=np.unique(aims[i]))
        if self.lost_grid is not None:
            seen = np.flatnonzero(counts > 0)
            self._anchor(np.unique(aims[seen][(used[seen] > 0) | restarted[aims[seen]]]))
        return UpdateRecord(negative, inflated, restarted, corrected, used, discarded,
                            gated_out)

    @property
    def n_modes(self) -> int:
        return len(self.q_modes)

    def predict(self) -> BoolArray:
        """Predict every track one step (mixing first for an IMM), then apply the map.

        Returns
        -------
        (M,) bool: tracks the map constraint corrected.
        """
        self.predict_modes()
        hit = self.reflect_off_map()
        # A reflected track is already on the map: truncating its Gaussian at the wall
        # would count the wall twice.
        hit |= self.apply_map(skip=hit)
        hit |= self.apply_buildings(reflect_dt=self.dt)
        if self.lost_grid is not None:
            self._lost_predict()
        return hit

    def reflect_off_map(self) -> BoolArray:
        """Reflect the modes that left the map off its walls (no-op unless
        ``reflect_walls``)."""
        M = len(self.means)
        if not self.reflect_walls:
            return np.zeros(M, dtype=bool)
        assert self.world is not None
        m, P, applied = map_reflection(self.mode_means, self.mode_covs, *self.world)
        hit = np.asarray(applied.any(axis=1))
        if hit.any():
            self.mode_means, self.mode_covs = m, P
            self.combine(np.flatnonzero(hit))
        return hit

    def apply_map(self, skip: BoolArray | None = None) -> BoolArray:
        """Truncate the modes that leave the map to it (no-op without a map), except the
        tracks ``skip`` ``(M,)`` (those just reflected off its walls)."""
        M = len(self.means)
        if self.world is None:
            return np.zeros(M, dtype=bool)
        m, P, applied, log_mass = map_constraint(self.mode_means, self.mode_covs, *self.world)
        hit = np.asarray(applied.any(axis=1))
        partial = skip is not None and bool(skip.any())
        if partial:
            assert skip is not None
            hit &= ~skip
        if hit.any():
            idx = np.flatnonzero(hit)
            if partial:
                self.mode_means[idx], self.mode_covs[idx] = m[idx], P[idx]
            else:
                self.mode_means, self.mode_covs = m, P
            self.reweight(idx, log_mass[idx])
            self.combine(idx)
        return hit

    def apply_buildings(self, reflect_dt: float | None = None,
                        targets: IntArray | None = None) -> BoolArray:
        """Restrict the modes of ``targets`` (default all) that reach into a building to
        the outside of the footprints (no-op without known buildings); with ``reflect_dt``
        (after a predict) the points that entered a building during the step are reflected
        at its walls first, as the targets are. Returns the tracks it changed ``(M,)``."""
        M = len(self.means)
        hit = np.zeros(M, dtype=bool)
        if not self.known_buildings:
            return hit
        assert self.buildings is not None
        rows = np.arange(M) if targets is None else np.asarray(targets, dtype=np.int64)
        m, P, applied, log_mass = building_constraint(self.mode_means[rows],
                                                      self.mode_covs[rows], self.buildings,
                                                      reflect_dt=reflect_dt)
        changed = np.asarray(applied.any(axis=1))
        if changed.any():
            idx = rows[changed]
            self.mode_means[idx], self.mode_covs[idx] = m[changed], P[changed]
            self.reweight(idx, log_mass[changed])
            self.combine(idx)
            hit[idx] = True
        return hit

    # ---------------------------------------------------------------- missed looks
    def miss(self, sensors: IntArray, targets: IntArray, sensor_xy: FloatArray,
             heading: FloatArray, kernel: Callable[..., Any] | None = None,
             fractions: FloatArray | None = None) -> tuple[BoolArray, BoolArray]:
        """Negative information of L missed looks, applied in the given (sensor) order.

        Parameters
        ----------
        sensors, targets : (L,) int;  sensor_xy : (L, 2);  heading : (L,)
        kernel : callable, optional
            The missed-look update (default :func:`sensorplan.tracking.missed.miss_update`).
        fractions : (L,) float, optional
            Filled with each look's probability, under its track just before it, of a
            gated detection (the mass it removed; mixed over the modes).

        Returns
        -------
        negative : (M,) bool    tracks that got a negative update
        inflated : (M,) bool    tracks that got the inflation instead (any mode)
        """
        if kernel is None:
            from .missed import miss_update                    # only runs that miss need it

            kernel = miss_update
        M = len(self.means)
        negative = np.zeros(M, dtype=bool)
        inflated = np.zeros(M, dtype=bool)
        for rnd in update_rounds(targets):
            i, j = sensors[rnd], targets[rnd]
            # A detection outside the gate would not have been used: the look says "no
            # gated detection" (with no gate the kernel's own rule, Pg = 1).
            gate_kw: dict[str, Any] = {} if self.gate is None else {
                "gate_probability": self.gate_probability}
            if self.buildings is not None:
                gate_kw["buildings"] = self.buildings
                if self.known_buildings:
                    gate_kw["footprints"] = self.buildings
            if self.n_modes == 1 and fractions is not None:
                m, P, infl, f1 = kernel(self.mode_means[j, 0], self.mode_covs[j, 0],
                                        sensor_xy[rnd], heading[rnd], self.table, i,
                                        return_fraction=True, **gate_kw)
                self.mode_means[j, 0], self.mode_covs[j, 0] = m, P
                fractions[rnd] = f1
            elif self.n_modes == 1:
                m, P, infl = kernel(self.mode_means[j, 0], self.mode_covs[j, 0], sensor_xy[rnd],
                                    heading[rnd], self.table, i, **gate_kw)
                self.mode_means[j, 0], self.mode_covs[j, 0] = m, P
            else:
                R = self.n_modes
                m, P, infl, f = kernel(self.mode_means[j], self.mode_covs[j],
                                       sensor_xy[rnd][:, None], heading[rnd][:, None],
                                       self.table, np.repeat(i[:, None], R, axis=1),
                                       return_fraction=True, **gate_kw)
                self.mode_means[j], self.mode_covs[j] = m, P
                if fractions is not None:
                    fractions[rnd] = np.einsum("br,br->b", self.mode_probs[j], f)
                # The mode's probability of the miss: the mass the look did not remove.
                self.reweight(j, np.log(np.maximum(1.0 - f, 1.0 / 512)))
                infl = infl.any(axis=1)
            self.combine(j)
            negative[j] = True
            inflated[j] |= infl
        return negative, inflated

    # ---------------------------------------------------------------- lost targets
    def _lost_args(self) -> tuple[FloatArray | None, float]:
        pg = 1.0 if self.gate_probability is None else float(self.gate_probability)
        return self.buildings, pg

    def _set_lost_tracks(self, rows: IntArray) -> None:
        """Report the grids of the lost tracks ``rows`` by their moments (every mode)."""
        from .lost import moments

        assert self.lost_grid is not None
        rows = np.asarray(rows, dtype=np.int64)
        if rows.size == 0:
            return
        mc = [moments(self.lost_grid, self.lost_weights[int(j)]) for j in rows]
        self.restart(rows, np.stack([m for m, _ in mc]), np.stack([c for _, c in mc]))

    def _lost_predict(self) -> None:
        """Count the steps since each anchor; diffuse the lost tracks' grids."""
        from .lost import diffuse, step_variance

        assert self.lost_grid is not None
        self.since += 1
        rows = np.flatnonzero(self.lost)
        for j in rows:
            self.lost_weights[int(j)] = diffuse(self.lost_grid, self.lost_weights[int(j)],
                                                step_variance(self.lost_grid,
                                                              int(self.since[j])))
        self._set_lost_tracks(rows)

    def _lost_misses(self, empty: IntArray, sensors: IntArray, aims: IntArray,
                     pos: FloatArray, head: FloatArray) -> tuple[BoolArray, BoolArray]:
        """The missed looks ``empty`` with the lost-target mode: the Gaussian tracks' (with
        the run's probability kept and every look logged), then the lost tracks' grids;
        then the tracks whose run of misses became too improbable are lost. Returns the
        tracks that got a negative update and those the Gaussian update inflated."""
        from .lost import detect_probability, miss, replay

        assert self.lost_grid is not None
        M = len(self.means)
        negative, inflated = np.zeros(M, dtype=bool), np.zeros(M, dtype=bool)
        if self.miss_update is None or empty.size == 0:
            return negative, inflated
        gaussian = empty[~self.lost[aims[empty]]]
        if gaussian.size:
            f = np.zeros(gaussian.size)
            negative, inflated = self.miss(sensors[gaussian], aims[gaussian], pos[gaussian],
                                    head[gaussian], kernel=self.miss_update, fractions=f)
            np.add.at(self.log_run, aims[gaussian], np.log(np.maximum(1.0 - f, 1e-300)))
            for n in gaussian:
                j = int(aims[n])
                self.miss_logs[j].add(int(self.since[j]), int(sensors[n]), pos[n],
                                      float(head[n]))
        blds, pg = self._lost_args()
        lost_looks = empty[self.lost[aims[empty]]]
        for n in lost_looks:
            j = int(aims[n])
            det = detect_probability(self.lost_grid, self.table, int(sensors[n]), pos[n],
                                     float(head[n]), blds, pg)
            self.lost_weights[j], _ = miss(self.lost_grid, self.lost_weights[j], det)
            negative[j] = True
        newly = np.flatnonzero(~self.lost & (self.log_run < self.log_lost))
        for r in newly:
            self.lost_weights[int(r)] = replay(self.lost_grid, self.anchor_means[r],
                                               self.anchor_covs[r], int(self.since[r]),
                                               self.miss_logs[r], self.table, blds, pg)
        self.lost[newly] = True
        self._set_lost_tracks(np.unique(np.concatenate([aims[lost_looks], newly]).astype(
            np.int64)))
        return negative, inflated

    def _lost_detections(self, i: IntArray, sensors: IntArray, aims: IntArray,
                         pos: FloatArray, head: FloatArray, looks: Looks, used: IntArray,
                         restarted: BoolArray) -> IntArray:
        """Re-initialise each lost track from the first of its looks ``i`` with a detection
        (the grid's posterior, or a restart from the detection when no cell passes the
        gate); returns the looks left for the Gaussian update."""
        from .lost import reacquire

        assert self.lost_grid is not None
        keep = np.ones(i.size, dtype=bool)
        for k, n in enumerate(i):
            j = int(aims[n])
            if not self.lost[j]:
                continue
            z = np.asarray(looks.detections[n], dtype=float)[0]
            got = reacquire(self.lost_grid, self.lost_weights.pop(j), z, pos[n],
                            float(head[n]), self.table, int(sensors[n]), self.gate)
            if got is None:
                nn = np.array([n])
                self._restart(np.zeros(1, dtype=np.int64), sensors[nn], aims[nn],
                              z[None], pos[nn], head[nn])
            else:
                self.restart(np.array([j]), got[0][None], got[1][None])
            self.lost[j] = False
            used[n] = 1
            restarted[j] = True
            keep[k] = False
        return i[keep]

    def _anchor(self, targets: IntArray) -> None:
        """Tracks ``targets`` were just detected: their current state is the new anchor."""
        t = np.asarray(targets, dtype=np.int64)
        if t.size == 0:
            return
        self.anchor_means[t] = self.means[t]
        self.anchor_covs[t] = self.covs[t]
        self.since[t] = 0
        self.log_run[t] = 0.0
        for j in t:
            self.miss_logs[int(j)] = MissLog.empty()

    # ---------------------------------------------------------------- detections
    def update_detections(self, sensors: IntArray, targets: IntArray, z: FloatArray,
                          sensor_xy: FloatArray, heading: FloatArray) -> LookResults:
        """Apply L detections, in the given (sensor) order per target, then the map.

        Detections of distinct targets are independent and applied as one batch; a target
        detected by several sensors is updated once per detection, in order, each gated and
        linearised at the track the previous one left (the sequential EKF).

        Parameters
        ----------
        sensors : (L,) int   row of ``table`` of the detecting sensor
        targets : (L,) int   track each detection belongs to
        z : (L, 2)           ``[r, phi]`` (m, rad)
        sensor_xy : (L, 2)
        heading : (L,)
        """
        L = len(targets)
        used = np.zeros(L, dtype=bool)
        gated_out = np.zeros(L, dtype=bool)
        restarted = np.zeros(L, dtype=bool)
        if L == 0:
            return LookResults(used, gated_out, restarted, np.zeros(len(self.means), dtype=bool))
        for idx in update_rounds(targets):
            ok = np.ones(len(idx), dtype=bool)
            if self.gate is not None:
                j = targets[idx]
                nu, S, _, _ = innovations(self.means[j], self.covs[j], z[idx], sensor_xy[idx],
                                          heading[idx], self.table, sensors[idx])
                ok = mahalanobis2(nu, S) < self.gate
                gated_out[idx[~ok]] = True
                if self.reacquire and not ok.all():
                    self._restart(idx[~ok], sensors, targets, z, sensor_xy, heading)
                    restarted[idx[~ok]] = True
            keep = idx[ok]
            if keep.size:
                self._update_modes(keep, sensors, targets, z, sensor_xy, heading)
                used[keep] = True
        return LookResults(used, gated_out, restarted, self.apply_map())

    def update_sets(self, sensors: IntArray, targets: IntArray, detections: list[FloatArray],
                    sensor_xy: FloatArray, heading: FloatArray,
                    kernel: Callable[..., Any] | None = None) -> SetResults:
        """Apply L looks that each returned a set of detections (the target's, false alarms).

        Looks are processed one at a time, in the given (sensor) order. A look's detections
        are gated with the track; then

        - the sensor reports false alarms (its ``clutter_rate`` > 0): probabilistic data
          association (``association = "pda"``) or the nearest gated detection
          (``"nearest"``); with no gated detection the look is a miss and gets the
          negative update for ``Pd < 1`` (``kernel``, default
          :func:`sensorplan.tracking.missed.miss_update`), if the tracker has missed-look updates;
        - it does not: the (single) detection is the target's, as in
          :meth:`update_detections`.

        Parameters
        ----------
        sensors, targets : (L,) int
        detections : list of L arrays ``(m_l, 2)``   ``[r, phi]`` of each look (m, rad)
        sensor_xy : (L, 2);  heading : (L,)

        Returns
        -------
        SetResults
        """
        M = len(self.means)
        L = len(targets)
        used = np.zeros(L, dtype=np.int64)
        discarded = np.zeros(L, dtype=np.int64)
        restarted = np.zeros(L, dtype=bool)
        negative = np.zeros(M, dtype=bool)
        for n in range(L):
            i, j = int(sensors[n]), int(targets[n])
            Z = np.asarray(detections[n], dtype=float).reshape(-1, 2)
            if Z.shape[0] == 0:
                continue
            clutter = self.table[i, CLUTTER_RATE] > 0.0
            if not clutter and not self.detects_all:
                if Z.shape[0] != 1:
                    raise ValueError(f"look {n}: {Z.shape[0]} detections from a sensor "
                                     "without false alarms")
                one = self.update_detections(np.array([i]), np.array([j]), Z,
                                             sensor_xy[n:n + 1], heading[n:n + 1])
                used[n], discarded[n] = int(one.used[0]), int(one.gated_out[0])
                restarted[n] = one.restarted[0]
                continue
            ok = np.ones(len(Z), dtype=bool)
            if self.gate is not None:
                rep = np.full(len(Z), i)
                nu, S, _, _ = innovations(np.repeat(self.means[j:j + 1], len(Z), 0),
                                          np.repeat(self.covs[j:j + 1], len(Z), 0), Z,
                                          np.repeat(sensor_xy[n:n + 1], len(Z), 0),
                                          np.repeat(heading[n:n + 1], len(Z), 0), self.table,
                                          rep)
                ok = mahalanobis2(nu, S) < self.gate
            discarded[n] = int((~ok).sum())
            gated = Z[ok]
            if len(gated) == 0:
                if kernel is not None:
                    neg, _ = self._miss_one(i, j, sensor_xy[n], heading[n], kernel)
                    negative |= neg
                continue
            if not clutter:
                # Every detection is some target's: the gated one nearest the track is its
                # target's (a detection outside the gate is another target's, never a
                # reason to restart).
                k = int(np.argmin(mahalanobis2(nu[ok], S[ok]))) if self.gate is not None else 0
                self._update_modes(np.zeros(1, dtype=np.int64), np.array([i]), np.array([j]),
                                   gated[k:k + 1], sensor_xy[n:n + 1], heading[n:n + 1])
                used[n] = 1
                continue
            if self.association == "nearest":
                gated = gated[[int(np.argmin(mahalanobis2(nu[ok], S[ok])))]] \
                    if self.gate is not None else gated[:1]
            pg = (self.gate_probability
                  if self.gate is not None and self.gate_probability is not None else 1.0)
            done = pda_update(self.mode_means[j], self.mode_covs[j], gated, sensor_xy[n],
                              float(heading[n]), self.table, i, pg)
            if done is not None:
                self.mode_means[j], self.mode_covs[j], log_den = done
                self.reweight(np.array([j]), log_den[None])
                self.combine(np.array([j]))
            used[n] = len(gated)
        return SetResults(used, discarded, restarted, negative, self.apply_map())

    def _miss_one(self, i: int, j: int, sxy: FloatArray, hd: float,
                  kernel: Callable[..., Any] | None) -> tuple[BoolArray, BoolArray]:
        return self.miss(np.array([i]), np.array([j]), np.asarray(sxy)[None],
                         np.array([hd]), kernel=kernel)

    def _update_modes(self, idx: IntArray, sensors: IntArray, targets: IntArray, z: FloatArray,
                      sensor_xy: FloatArray, heading: FloatArray) -> None:
        j = targets[idx]
        if self.n_modes == 1:
            self.mode_means[j, 0], self.mode_covs[j, 0] = update(
                self.mode_means[j, 0], self.mode_covs[j, 0], z[idx], sensor_xy[idx],
                heading[idx], self.table, sensors[idx])
        else:
            R = self.n_modes
            x = self.mode_means[j].reshape(-1, 4)
            P = self.mode_covs[j].reshape(-1, 4, 4)
            zr, sxy, hd = (np.repeat(a, R, axis=0) for a in (z[idx], sensor_xy[idx],
                                                             heading[idx]))
            sr = np.repeat(sensors[idx], R, axis=0)
            nu, S, Hp, var = innovations(x, P, zr, sxy, hd, self.table, sr)
            # Mode likelihoods N(nu; 0, S), in logs.
            logl = -0.5 * mahalanobis2(nu, S) - 0.5 * np.linalg.slogdet(S)[1] \
                - GATE_DOF * 0.5 * math.log(2.0 * math.pi)
            xn, Pn = position_update(x, P, nu, Hp, var)
            self.mode_means[j] = xn.reshape(-1, R, 4)
            self.mode_covs[j] = Pn.reshape(-1, R, 4, 4)
            self.reweight(j, logl.reshape(-1, R))
        self.combine(j)

    def _restart(self, idx: IntArray, sensors: IntArray, targets: IntArray, z: FloatArray,
                 sensor_xy: FloatArray, heading: FloatArray) -> None:
        """Restart the tracks of detections ``idx`` at their inverse measurements."""
        j = targets[idx]
        xy, C = inverse_looks(self.table, sensors[idx], z[idx], sensor_xy[idx], heading[idx])
        P = np.zeros((len(idx), 4, 4))
        P[:, :2, :2] = C
        P[:, 2, 2], P[:, 3, 3] = self.restart_velocity_var
        x = np.zeros((len(idx), 4))
        x[:, :2] = xy
        self.restart(j, x, P)
