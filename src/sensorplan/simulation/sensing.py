"""What the sensors see of the truth in one step: each look's detections and what they were.

:class:`Sensing` holds a run's sensors and every random draw of their sensing, made up front
from the run's own streams (measurement noise, detection, false alarms), so that every
method of a study sees the same draws (common random numbers). Its :meth:`Sensing.look`
turns the platforms' poses and aims into the :class:`~sensorplan.tracking.base.Looks` a
tracker updates with, and the facts only the simulator knows (:class:`Sensed`).
"""

from __future__ import annotations

import numpy as np

from .._types import BoolArray, FloatArray, IntArray, IntegerArray
from ..models import radar
from ..models.angles import wrap_angle
from ..models.sensors import ALTITUDE, ALTITUDE2, CLUTTER_RATE, SWERLING
from ..tracking.base import Looks
from .episode import Sensed
from .scenario import LOOK_DETECTS


#: Lowest height (m) above a radar that a recorded altitude is taken as: the radar model
#: needs the target below or above the antenna, never level with it.
MIN_HEIGHT = 1.0


def at_heights(table: FloatArray, rows: IntArray, heights: FloatArray) -> FloatArray:
    """The radar rows ``table[rows]`` ``(P, C)`` with each pair's own height above the
    radar, ``heights`` ``(P,)`` (m, at least :data:`MIN_HEIGHT`), in place of the table's
    altitude: what a ground radar sees of an aircraft at that height (the model's geometry
    mirrored, the beam's depression read as its elevation)."""
    out = np.array(table[rows], dtype=float)
    h = np.maximum(np.asarray(heights, dtype=float), MIN_HEIGHT)
    out[:, ALTITUDE] = h
    out[:, ALTITUDE2] = h * h
    return out


def _imperfect(table: FloatArray) -> bool:
    """Whether some sensor misses targets in view or reports false alarms."""
    return bool(table[:, SWERLING].any() or table[:, CLUTTER_RATE].any())


class DetectionDraws:
    """A run's detection outcomes and false alarms, drawn up front from their own streams.

    Per sensor and step: one uniform decides whether a target in view is detected
    (``u < Pd``), drawn whether the sensor looks or not; a Poisson count of false alarms
    (mean ``clutter_rate``) and, per false alarm, two uniforms (its ground range and
    azimuth, uniform in area over the sensing region) and two standard normals (its
    measurement noise). The draws depend only on the run's seed, so every method of a study
    sees the same ones (common random numbers).
    """

    def __init__(self, table: FloatArray, streams: dict[str, np.random.SeedSequence],
                 S: int) -> None:
        N = len(table)
        self.table = table
        self.u = np.stack([np.random.default_rng(c).random(S)
                           for c in streams["detection"].spawn(N)], axis=1)   # (S, N)
        self.counts = np.zeros((S, N), dtype=np.int64)
        self.points: list[list[tuple[FloatArray, FloatArray]]] = []
        for i, c in enumerate(streams["clutter"].spawn(N)):
            rng = np.random.default_rng(c)
            lam = table[i, CLUTTER_RATE]
            counts = rng.poisson(lam, S) if lam > 0 else np.zeros(S, dtype=np.int64)
            draws = rng.random((int(counts.sum()), 2))
            normals = rng.standard_normal((int(counts.sum()), 2))
            self.counts[:, i] = counts
            split = np.cumsum(counts)[:-1]
            self.points.append(list(zip(np.split(draws, split), np.split(normals, split))))

    def detected(self, t: int, target_xy: FloatArray, sensor_xy: FloatArray,
                 table: FloatArray | None = None) -> BoolArray:
        """Whether each sensor's look would detect its target if in view, at step t
        (``table``: its rows in place of the run's, :func:`at_heights`)."""
        rows = self.table if table is None else table
        pd = radar.detection_probabilities(rows, np.arange(len(rows)), target_xy, sensor_xy)
        return self.u[t - 1] < pd

    def looks(self, t: int, seen: BoolArray, z: FloatArray, pos: FloatArray, head: FloatArray,
              assigned: BoolArray) -> tuple[list[FloatArray], IntegerArray]:
        """Each sensor's detections at step t (its target's if seen, then its false alarms
        in the sensing region), and its number of false alarms."""
        sets, false = [], np.zeros(len(self.table), dtype=np.int16)
        for i in range(len(self.table)):
            clutter = self._clutter_of(i, t, pos[i], head[i]) if assigned[i] \
                else np.zeros((0, 2))
            false[i] = len(clutter)
            sets.append(np.concatenate(([z[i:i + 1]] if seen[i] else []) + [clutter]))
        return sets, false

    def _clutter_of(self, i: int, t: int, sxy: FloatArray, heading: float) -> FloatArray:
        u, n = self.points[i][t - 1]
        return radar.false_alarms(self.table, i, sxy, heading, u, n)


class Sensing:
    """A run's sensors looking at the truth (see the module docstring).

    Parameters
    ----------
    table : (N, C) radar table
    buildings : (K, 5)   buildings that can hide a target (none: ``(0, 5)``)
    streams : the run's seed sequences (:func:`~sensorplan.simulation.run.run_streams`)
    steps : S, the run's number of steps
    look_detects : "target" or "all"   what a look detects (:meth:`look`)
    aims_at_targets : whether an aim is a target slot (a tracker of known targets) or a
        track of a multi-target tracker, which has no target to miss

    Every sensor draws its two standard normals of measurement noise at every step, whether
    it looks or not, so the noise of one sensor does not depend on the others' plans.
    """

    def __init__(self, table: FloatArray, buildings: FloatArray,
                 streams: dict[str, np.random.SeedSequence], steps: int,
                 look_detects: str = "target", aims_at_targets: bool = True) -> None:
        if look_detects not in LOOK_DETECTS:
            raise ValueError(f"look_detects must be one of {LOOK_DETECTS}, got {look_detects!r}")
        N = len(table)
        self.table = table
        self.buildings = buildings
        self.look_detects = look_detects
        self.aims_at_targets = aims_at_targets
        self.targets = TargetDraws(streams["target_detection"], steps, N)
        self.noise = np.stack([np.random.default_rng(c).standard_normal((steps, 2))
                               for c in streams["noise"].spawn(N)], axis=1)     # (S, N, 2)
        self.draws = (DetectionDraws(table, streams, steps)
                      if _imperfect(table) or look_detects == "all" else None)
        self._index = np.arange(N)

    def look(self, t: int, truth: FloatArray, positions: FloatArray, headings: FloatArray,
             aimed: IntArray, alive: BoolArray | None = None,
             heights: FloatArray | None = None) -> tuple[Looks, Sensed]:
        """Step ``t``'s looks: sensor i, at ``positions[i]`` with ``headings[i]``, looks at
        target ``aimed[i]`` (-1: it does not look) of the true states ``truth`` ``(M, 4)``,
        of which ``alive`` ``(M,)`` are in the world (default: all).

        Visibility and the sampled noise use the true position; a building in the line of
        sight hides the target (false alarms still occur). With ``look_detects = "all"`` a
        look detects every live target in its sensing region (:meth:`look_all`).

        ``heights`` ``(M,)``: each target's own height above the radars (m), a recorded
        truth's (:class:`~sensorplan.models.traffic.TrafficTruth`). Visibility, detection and
        the noise are then those of the true slant range and elevation (:func:`at_heights`);
        the measurement's mean stays the radar model's at the table's altitude, the
        reference height that trackers and planners assume: the radar corrects its slant
        range with the target's reported altitude, as an air traffic radar does with the
        altitude its secondary radar or ADS-B reports.
        """
        if self.look_detects == "all":
            return self.look_all(t, truth, positions, headings, aimed, alive, heights)
        table, idx = self.table, self._index
        assigned = aimed >= 0
        tj = np.maximum(aimed, 0)
        h, _, var, seen = radar.measure_looks(table, idx, truth[tj, :2], positions, headings)
        pd_table, pd_rows = table, idx
        if heights is not None:
            pd_table, pd_rows = at_heights(table, idx, heights[tj]), idx
            _, _, var, seen = radar.measure_looks(pd_table, pd_rows, truth[tj, :2], positions,
                                                  headings)
        seen &= assigned
        if len(self.buildings):
            seen &= ~radar.hidden_looks(self.buildings, positions, table[:, ALTITUDE],
                                        truth[tj, :2])
        if self.draws is not None:
            seen &= self.draws.detected(t, truth[tj, :2], positions, pd_table)
        z = h + np.sqrt(var) * self.noise[t - 1]
        z[:, 1] = wrap_angle(z[:, 1])
        i = idx[assigned]
        if self.draws is not None:
            sets, false = self.draws.looks(t, seen, z, positions, headings, assigned)
            detections = tuple(sets[n] for n in i)
        else:
            false = np.zeros(len(table), dtype=np.int16)
            detections = tuple(z[n:n + 1] if seen[n] else z[n:n][:0] for n in i)
        looks = Looks(sensors=i, aims=aimed[i], positions=positions[i], headings=headings[i],
                      detections=detections)
        return looks, Sensed(seen=seen, missed=assigned & ~seen, false_alarms=false)

    def look_all(self, t: int, truth: FloatArray, positions: FloatArray, headings: FloatArray,
                 aimed: IntArray, alive: BoolArray | None = None,
                 heights: FloatArray | None = None) -> tuple[Looks, Sensed]:
        """Step ``t``'s looks when a look detects every live target in its sensing region.

        Each (sensor, target) pair in view and in sight is detected with the radar's Pd,
        decided by a uniform of the target's own stream (:class:`TargetDraws`), and measured
        with the target's own noise; a look's detections are its detected targets' (in the
        targets' order) followed by its false alarms. ``heights`` as in :meth:`look`.
        """
        table, N, M = self.table, len(self.table), len(truth)
        live = np.ones(M, dtype=bool) if alive is None else np.asarray(alive, dtype=bool)
        # Every sensor looks along its heading, at a track or not: what it sees is what a
        # multi-target tracker learns from.
        assigned = np.ones(N, dtype=bool)
        i = self._index[assigned]
        j = np.flatnonzero(live)
        ii, jj = np.repeat(i, len(j)), np.tile(j, len(i))                   # (L K,)
        xy = truth[jj, :2]
        h, _, var, seen = radar.measure_looks(table, ii, xy, positions[ii], headings[ii])
        pd_table, pd_rows = table, ii
        if heights is not None:
            pd_table, pd_rows = at_heights(table, ii, heights[jj]), np.arange(len(ii))
            _, _, var, seen = radar.measure_looks(pd_table, pd_rows, xy, positions[ii],
                                                  headings[ii])
        if len(self.buildings) and len(ii):
            seen &= ~radar.hidden_looks(self.buildings, positions[ii], table[ii, ALTITUDE], xy)
        u, e = self.targets.draws(t, ii, jj)
        if _imperfect(table):
            seen &= u < radar.detection_probabilities(pd_table, pd_rows, xy, positions[ii])
        z = h + np.sqrt(np.where(seen[:, None], var, 0.0)) * e
        z[:, 1] = wrap_angle(z[:, 1])
        measured = np.zeros((M, N), dtype=bool)
        measured[jj[seen], ii[seen]] = True
        clutter = (self.draws.looks(t, np.zeros(N, dtype=bool), np.zeros((N, 2)), positions,
                                    headings, assigned)
                   if self.draws is not None else None)
        detections, false = [], np.zeros(N, dtype=np.int16)
        for n in i:
            own = z[(ii == n) & seen]
            extra = clutter[0][n] if clutter is not None else np.zeros((0, 2))
            if clutter is not None:
                false[n] = clutter[1][n]
            detections.append(np.concatenate([own, extra]))
        # A multi-target tracker aims at its own tracks, which are no target slots (it may
        # report more tracks than there are targets): no look then has a target to miss.
        at_target = aimed >= 0 if self.aims_at_targets else np.zeros(N, dtype=bool)
        aimed_seen = np.zeros(N, dtype=bool)
        on = i[at_target[i]]
        aimed_seen[on] = measured[aimed[on], on]
        looks = Looks(sensors=i, aims=aimed[i], positions=positions[i], headings=headings[i],
                      detections=tuple(detections))
        return looks, Sensed(seen=aimed_seen, missed=at_target & ~aimed_seen,
                             false_alarms=false, measured=measured)



class TargetDraws:
    """Each target's own detection draws and measurement noise, per sensor and step.

    Target slot k's draws come from child k of the run's ``target_detection`` stream, made
    when first needed: a target born later, or another target's presence, changes nothing
    of them. Per step and sensor: one uniform (detected if below Pd) and two standard
    normals (the measurement noise), whether the sensor sees the target or not.
    """

    def __init__(self, stream: np.random.SeedSequence, steps: int, n_sensors: int) -> None:
        self.stream, self.steps, self.n_sensors = stream, steps, n_sensors
        self._u: list[FloatArray] = []
        self._e: list[FloatArray] = []

    def _grow(self, slots: int) -> None:
        base = self.stream
        for k in range(len(self._u), slots):
            rng = np.random.default_rng(np.random.SeedSequence(
                base.entropy, spawn_key=tuple(base.spawn_key) + (k,), pool_size=base.pool_size))
            self._u.append(rng.random((self.steps, self.n_sensors)))
            self._e.append(rng.standard_normal((self.steps, self.n_sensors, 2)))

    def draws(self, t: int, sensors: IntArray, slots: IntArray) -> tuple[FloatArray, FloatArray]:
        """Step ``t``'s uniforms ``(P,)`` and normals ``(P, 2)`` of (sensor, target) pairs."""
        if len(slots) == 0:
            return np.zeros(0), np.zeros((0, 2))
        self._grow(int(slots.max()) + 1)
        u = np.array([self._u[k][t - 1, i] for i, k in zip(sensors, slots)])
        e = np.array([self._e[k][t - 1, i] for i, k in zip(sensors, slots)])
        return u, e
