"""The study model: named methods run on the same paired runs of one scenario."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config.scenario import scenario_from_dict, scenario_to_dict
from ..errors import ConfigError
from ..simulation.scenario import Scenario
from ..simulation.settings import RunSettings, declared

#: Layout version of a study directory (2: tracker settings in a ``tracker`` sub-table;
#: 4: the ``sensors`` table's ``label``, the looked-at track's).
FORMAT = "sensorplan-study/4"
#: Layouts this version reads (a study of an older one is read, not resumed: its ``sensors``
#: table gets ``label`` from ``target`` for methods that track known targets, -1 otherwise).
READABLE_FORMATS = ("sensorplan-study/3", FORMAT)
#: Run settings that are study-wide (top-level keys of a study file), not per method.
STUDY_KEYS = tuple(f.name for f, _ in declared(RunSettings, "run"))


@dataclass(frozen=True)
class Method:
    """One named way of planning and tracking: everything a run needs besides its seed."""

    name: str
    settings: RunSettings

    def to_dict(self) -> dict[str, Any]:
        """The method as in ``config.resolved.json``: its name and every per-method
        setting (the study-wide ones, such as ``steps``, are the study's)."""
        d = self.settings.to_dict()
        for key in STUDY_KEYS:
            d.pop(key)
        return {"name": self.name, **d}


#: Tracker settings added after studies had run, with the value those studies ran with (a
#: track reported exactly while its existence is at least the report threshold; no
#: background births; one motion model in every PMB Bernoulli; an isotropic velocity prior
#: for a target first detected; every track with the tracker survival; recycled tracks left
#: on the grid where they were; every Bernoulli's hypotheses merged after a look, into one
#: Gaussian).
TRACKER_SETTINGS_ADDED = {"termination_threshold": 1.0, "background_birth_rate": 0.0,
                          "bernoulli_model": "cv", "birth_velocity": "isotropic",
                          "established_survival": 0.0, "established_existence": 0.99,
                          "recycle_motion": "static", "split_existence": 0.0,
                          "density_components": 1}


def planned_as_written(method: Mapping[str, Any]) -> dict[str, Any]:
    """A method of a ``config.resolved.json`` with the settings it ran with where it
    predates them: before ``tracker.planning_threshold`` existed planning saw the reported
    tracks only, so a method without it gets its report threshold (0.5 unless written), not
    today's default; likewise the reward, ``unreported``, ``find_tail``,
    ``track_existence`` and :data:`TRACKER_SETTINGS_ADDED`."""
    m = dict(method)
    # Before the reward existed, every method planned for information.
    m.setdefault("reward", "information")
    m.setdefault("unreported", "localise")
    m.setdefault("find_tail", 0)
    m.setdefault("track_existence", "fixed")
    tracker = dict(m.get("tracker", {}))
    tracker.setdefault("planning_threshold", tracker.get("report_threshold", 0.5))
    for key, value in TRACKER_SETTINGS_ADDED.items():
        tracker.setdefault(key, value)
    m["tracker"] = tracker
    return m


@dataclass(frozen=True)
class Study:
    """A Monte Carlo study: ``runs`` paired runs of ``steps`` steps for every method.

    Attributes
    ----------
    scenario : Scenario
    runs, steps : int
    seed : int                   root of the study's ``SeedSequence``
    methods : tuple of Method    unique names; every ``settings.steps == steps``
    description : str
    scenario_source : str        where the scenario came from (provenance only)
    """

    scenario: Scenario
    runs: int
    steps: int
    seed: int
    methods: tuple[Method, ...]
    description: str = ""
    scenario_source: str = "preset paper"

    def __post_init__(self) -> None:
        object.__setattr__(self, "methods", tuple(self.methods))
        for name in ("runs", "steps"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(name, f"must be an integer >= 1, got {v!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise ConfigError("seed", f"must be an integer >= 0, got {self.seed!r}")
        if not self.methods:
            raise ConfigError("methods", "at least one method is required")
        names = [m.name for m in self.methods]
        for i, m in enumerate(self.methods):
            if names.index(m.name) != i:
                raise ConfigError(f"methods[{i}].name", f"duplicate method name {m.name!r}")
            for key in STUDY_KEYS:
                if getattr(m.settings, key) != getattr(self.methods[0].settings, key):
                    raise ConfigError(f"methods[{i}].{key}", "must be the same for every method")
            if m.settings.steps != self.steps:
                raise ConfigError(f"methods[{i}].steps", "must equal the study's steps")

    @property
    def method_names(self) -> list[str]:
        return [m.name for m in self.methods]

    def run_seed(self, run: int) -> np.random.SeedSequence:
        """Run ``run``'s seed: child ``run`` of ``SeedSequence(seed).spawn(runs)``.

        It does not depend on ``runs``, so a study with more runs shares its first runs.
        """
        return np.random.SeedSequence(self.seed, spawn_key=(int(run),))

    def tasks(self) -> list[tuple[int, int]]:
        """Every (run, method index), run-major."""
        return [(r, m) for r in range(self.runs) for m in range(len(self.methods))]

    def resolved(self) -> dict[str, Any]:
        """JSON-ready study with every default filled in (``config.resolved.json``)."""
        shared = self.methods[0].settings.to_dict()
        return {"format": FORMAT, "description": self.description,
                "scenario_source": self.scenario_source, "runs": self.runs,
                **{k: shared[k] for k in STUDY_KEYS}, "seed": self.seed,
                "scenario": scenario_to_dict(self.scenario),
                "methods": [m.to_dict() for m in self.methods]}

    @classmethod
    def from_resolved(cls, data: Mapping[str, Any]) -> Study:
        """Inverse of :meth:`resolved` (the report rebuilds the study from its directory)."""
        # A key missing from a directory written before it existed takes its default.
        shared = {k: data[k] for k in STUDY_KEYS if k in data}
        methods = []
        for m in data["methods"]:
            m = dict(m)
            name = m.pop("name")
            m = planned_as_written(m)
            # Trusted: the planner is not imported (the report of a study run with a
            # planner from another package must not need that package).
            methods.append(Method(name, RunSettings.from_dict({**m, **shared}, trusted=True)))
        return cls(scenario=scenario_from_dict(data["scenario"]), runs=int(data["runs"]),
                   steps=int(data["steps"]), seed=int(data["seed"]), methods=tuple(methods),
                   description=data.get("description", ""),
                   scenario_source=data.get("scenario_source", ""))
