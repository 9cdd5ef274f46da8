r"""Stone Soup interop: our radar, platforms and planners inside a Stone Soup tracking loop.

Install with the extra ``sensorplan[stonesoup]``. Only this module imports Stone Soup.

What is here (``docs/stonesoup.md`` has the full mapping and its limits):

- **Converters**, exact both ways: Stone Soup orders a target state ``[x, vx, y, vy]``,
  sensorplan ``[x, y, vx, vy]``; :func:`to_stonesoup_mean`, :func:`to_stonesoup_cov`,
  :func:`to_gaussian_state`, :func:`to_tracks` and their inverses permute entries, nothing
  else.
- :class:`RadarMeasurementModel`: sensorplan's radar as a Stone Soup measurement model
  (slant range with altitude, azimuth, SNR-dependent noise): ``function``, an analytic
  ``jacobian`` and ``covar`` evaluated at a state, so Stone Soup's ``ExtendedKalmanUpdater``
  runs on it.
- Actionables: :class:`LatticeMovable` (a platform movement controller whose actions are
  the lattice moves inside the map) and :class:`SensorplanRadar` (the radar, mounted on such a
  platform, whose action is *where to look*: an :class:`AimAction` with a ground point; the
  heading then follows the heading rule from the platform's position).
- Missed detections and false alarms: a radar whose ``params`` say ``detection="swerling1"``
  misses a target in view with probability ``1 - Pd``, and one with ``clutter_rate > 0``
  reports false alarms as Stone Soup ``Clutter`` in its sensing region;
  :meth:`SensorplanRadar.detection_probability` and
  :meth:`SensorplanRadar.clutter_spatial_density` give what Stone Soup's ``PDAHypothesiser``
  needs (``prob_detect``, ``clutter_spatial_density``); :func:`ordered_detections` orders a
  look's detections for bit-identical runs.
- :class:`SensorplanManager`: a Stone Soup ``SensorManager`` that turns the tracks and the
  actionables into a :class:`~sensorplan.planners.problem.PlanningProblem`, runs any registered
  planner (rolling horizon: every call plans K epochs and returns the first) and returns
  Stone Soup actions.
- :class:`MutualInformationReward`: a reward for Stone Soup's own sensor managers
  (brute force, greedy, MCTS) that is our one-step objective with ``visibility = "mean"``:
  the sum over tracks of ``0.5 log det P_prior / det P_post`` after Stone Soup's predictor
  and updater apply every look whose target's predicted mean is in the field of view.

- Search: a radar's ``search_sectors`` are offered as aims at :class:`SearchSector`\ s
  beside the tracks; :class:`SearchAndTrackReward` (for Stone Soup's own managers) and
  :class:`SensorplanManager` with ``search="on"`` value a look by the track information it
  gives (weighted by existence) plus the undetected targets it is expected to find, from
  :meth:`PMBStoneSoupTracker.undetected_intensity`.

- :class:`PMBStoneSoupTracker`: sensorplan's Poisson multi-Bernoulli tracker as a Stone Soup
  tracker (iterates ``(time, tracks)`` over a detector, or takes one scan at a time) for
  Stone Soup's ``LinearGaussian`` position model or for aimed radars (``radars``); its
  tracks' states are
  :class:`BernoulliGaussianState`\ s with the existence probability, their ids the labels.

- :class:`MapRect` ``(x0, y0, width, height)``: the map in world coordinates with any origin;
  the manager plans in the core's frame (world minus the origin) and acts in world
  coordinates.
- Stone Soup's habits: with no seed or generator, the radar and its measurement model draw
  from NumPy's global state (``np.random.seed`` makes a run repeatable); 6-D tracks
  ``[x, vx, y, vy, z, vz]`` (or any layout named by ``position_mapping`` and
  ``velocity_mapping``) are planned on their ground marginal; no tracks gives a
  stay-and-hold configuration; ``stonesoup.serialise.YAML`` saves and loads a manager setup
  (importing this module registers the readers it needs, see :func:`yaml_init`).

Timing convention (Stone Soup's): ``choose_actions(tracks, timestamp)`` receives tracks at
time ``t0`` and returns actions that end at ``timestamp``; the actionables ``act`` at the
start of the epoch, then measure. The planning problem's time 0 is ``t0`` and its step is
the manager's ``dt``.
"""

from ._actionables import (AimAction, AimActionGenerator, LatticeMovable, LatticeMoveAction,
                           LatticeMoveActionGenerator, SearchSector, SensorplanRadar,
                           set_aim_candidates)
from ._convert import (STONESOUP_ORDER, from_gaussian_state, from_stonesoup_cov,
                       from_stonesoup_mean, from_tracks, ground_index, ordered_tracks,
                       to_gaussian_state, to_ground_truth_state, to_stonesoup_cov,
                       to_stonesoup_mean, to_tracks)
from ._detection import ordered_detections
from ._manager import (MutualInformationReward, SearchAndTrackReward, SensorplanManager,
                       execute)
from ._measurement import RadarMeasurementModel
from ._pmb import BernoulliGaussianState, PMBStoneSoupTracker, gaussian_cell_masses
from ._serialise import yaml_init
from ._world import DEFAULT_WORLD, MapRect

__all__ = ["DEFAULT_WORLD", "STONESOUP_ORDER", "AimAction", "AimActionGenerator",
           "BernoulliGaussianState", "PMBStoneSoupTracker", "gaussian_cell_masses",
           "LatticeMovable", "LatticeMoveAction", "LatticeMoveActionGenerator", "MapRect",
           "MutualInformationReward", "RadarMeasurementModel", "SearchAndTrackReward",
           "SearchSector", "SensorplanManager",
           "SensorplanRadar", "execute", "from_gaussian_state", "from_stonesoup_cov",
           "from_stonesoup_mean", "from_tracks", "ground_index", "ordered_detections",
           "ordered_tracks", "set_aim_candidates", "to_gaussian_state",
           "to_ground_truth_state", "to_stonesoup_cov", "to_stonesoup_mean", "to_tracks",
           "yaml_init"]
