"""The planning modes: which planned looks count in Phi, and how Phi sums them.

Kept apart from :mod:`sensorplan.planners.problem` so that the run settings (and the command line's
help) can name them without importing numpy.
"""

from __future__ import annotations

from typing import Literal

Visibility = Literal["probabilistic", "mean"]
Objective = Literal["terminal", "cumulative"]
#: ``probabilistic``: a look counts weighted by the chance its target is in view;
#: ``mean``: a look counts iff the predicted mean is in view (the paper's).
VISIBILITY_MODES = ("probabilistic", "mean")
#: ``terminal``: information at the end of the horizon (the paper's); ``cumulative``: summed
#: over its steps.
OBJECTIVES = ("terminal", "cumulative")
#: ``aware``: a planned look also counts its detection probability and the clutter;
#: ``ignore``: only whether its target is in view.
PLANNING_DETECTIONS = ("ignore", "aware")
#: ``aware``: a planned look counts with the probability that no building hides its target;
#: ``ignore``: the planner does not know the buildings.
PLANNING_OCCLUSIONS = ("ignore", "aware")
#: ``off``: looks point at tracks only; ``on``: a look may also point at a search sector, and
#: Phi adds the value of the undetected targets the plan is expected to find.
SEARCH_MODES = ("off", "on")
#: ``information``: Phi is the tracks' information plus the value of the targets found;
#: ``gospa``: Phi is the reduction of the expected GOSPA bound the plan buys (needs search on).
REWARDS = ("information", "gospa")
#: How the ``gospa`` reward values a planned track the tracker does not report: ``localise``
#: as a reported one (by its covariance's bound reduction); ``confirm`` as a target to find
#: (its existence times the chance a look detects it times the bound a find removes).
UNREPORTED_MODES = ("localise", "confirm")
#: What a look does to a reported track in the ``gospa`` reward: ``fixed``: it shrinks the
#: track's covariance only (the track's existence is taken as it is); ``resolved``: it also
#: tells whether the track exists (a detection confirms it, a miss lowers its existence,
#: and a track whose existence falls far enough is better not reported).
TRACK_EXISTENCE_MODES = ("fixed", "resolved")
