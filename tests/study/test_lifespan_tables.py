"""A study of targets that are born and die, tracked by a multi-target tracker: its tables hold
every live target's true position and every reported track's label, position and existence
at every step, enough to recompute GOSPA with nothing but numpy and the standard library; the
replay of one of its runs reproduces what it stored."""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

C = 50.0        # the cut-off the study tables document (set_metrics.GOSPA_CUTOFF)


def _search_study():
    from sensorplan import study as studies
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import RunSettings, TrackerSettings

    # More births than the preset's and a survival below 1, so that a short run has both;
    # the tracker's birth and survival model is the truth's.
    scenario = dataclasses.replace(search_scenario(), look_detects="all", birth_rate=0.25,
                                   survival_probability=0.97)
    tracker = TrackerSettings(kind="pmb", birth_rate=0.25, survival_probability=0.97)
    settings = RunSettings(planner="pg", steps=25, tracker=tracker)
    return studies.Study(scenario=scenario, runs=2, steps=25, seed=90417,
                         methods=(studies.Method("pmb", settings),),
                         scenario_source="search (test)")


@pytest.fixture(scope="module")
def search_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from sensorplan import study as studies

    out = tmp_path_factory.mktemp("lifespan") / "study"
    studies.run_study(_search_study(), out, workers=1)
    return out


def brute_force_gospa(x: np.ndarray, y: np.ndarray, c: float) -> tuple[float, float, float,
                                                                         float]:
    """GOSPA (alpha = 2, p = 2) and its localisation, missed and false parts by trying every
    injective assignment of the smaller set into the larger one."""
    n, m = len(x), len(y)
    best = (math.inf, 0.0, 0.0, 0.0)
    small, large = (x, y) if n <= m else (y, x)
    for perm in itertools.permutations(range(len(large)), len(small)):
        d2 = [float(np.sum((small[i] - large[j]) ** 2)) for i, j in enumerate(perm)]
        pairs = [v for v in d2 if v < c * c]
        k = len(pairs)
        loc = math.fsum(pairs)
        missed, false = 0.5 * c * c * (n - k), 0.5 * c * c * (m - k)
        total = loc + missed + false
        if total < best[0]:
            best = (total, loc, missed, false)
    return math.sqrt(best[0]), best[1], best[2], best[3]


def test_gospa_recomputed_from_the_tables_matches_the_stored_gospa(search_dir: Path) -> None:
    steps = pd.read_parquet(search_dir / "steps.parquet")
    tracks = pd.read_parquet(search_dir / "tracks.parquet")
    gospa = pd.read_parquet(search_dir / "gospa.parquet")
    # The runs have what the test is about: births, deaths, and tracks that come and go.
    alive = steps.groupby(["run", "target"])["step"].agg(["min", "max"])
    assert (alive["min"] > 0).any(), "no target was born"
    assert (alive["max"] < 25).any(), "no target died"
    labels = tracks.groupby(["run", "label"])["step"].agg(["min", "max"])
    assert (labels["min"] > 0).any(), "no track was confirmed"
    checked = 0
    for row in gospa.itertuples():
        x = steps[(steps["run"] == row.run) & (steps["step"] == row.step)][["x", "y"]]
        y = tracks[(tracks["run"] == row.run) & (tracks["step"] == row.step)][["x", "y"]]
        assert (row.targets, row.tracks) == (len(x), len(y))
        if max(len(x), len(y)) > 8:           # 8! assignments at most
            continue
        d, loc, missed, false = brute_force_gospa(x.to_numpy(float), y.to_numpy(float), C)
        np.testing.assert_allclose(row.gospa, d, rtol=0, atol=1e-9)
        np.testing.assert_allclose([row.localisation, row.missed, row.false],
                                   [loc, missed, false], rtol=1e-12, atol=1e-9)
        checked += 1
    assert checked >= 0.9 * len(gospa)


def test_the_live_targets_are_those_of_the_run(search_dir: Path) -> None:
    """Every live target of a replayed run is in the steps table with its true position and
    its slot's kind, nothing else is; the replay reproduces the stored run, tracks included."""
    from sensorplan.study.replay import replay_run

    rep = replay_run(search_dir, 1, "pmb")
    assert rep.stored and rep.reproduced, rep.differences
    assert "tracks.existence" in rep.differences
    ep = rep.episode
    steps = pd.read_parquet(search_dir / "steps.parquet")
    mine = steps[steps["run"] == 1].sort_values(["step", "target"])
    s, j = np.nonzero(ep.alive)
    np.testing.assert_array_equal(mine["step"], s)
    np.testing.assert_array_equal(mine["target"], j)
    np.testing.assert_array_equal(mine[["x", "y"]].to_numpy(), ep.truth[s, j, :2])
    templates = _search_study().scenario.target_kinds
    assert list(mine["kind"]) == [templates[k % len(templates)] for k in j]
    assert ep.alive.shape[1] > len(templates)       # more slots than templates


def test_the_sensors_table_names_the_looked_at_track(search_dir: Path) -> None:
    """``label`` is the label of the track at the looked index of the set each epoch started
    from (steps_per_epoch 1: the set of the step before)."""
    sensors = pd.read_parquet(search_dir / "sensors.parquet")
    tracks = pd.read_parquet(search_dir / "tracks.parquet")
    from sensorplan.study.replay import replay_run

    ep = replay_run(search_dir, 0, "pmb").episode
    mine = sensors[sensors["run"] == 0].sort_values(["step", "sensor"])
    looked = mine.pivot(index="step", columns="sensor", values="target").to_numpy()
    label = mine.pivot(index="step", columns="sensor", values="label").to_numpy()
    mine_tracks = tracks[tracks["run"] == 0]
    assert (label[1:] >= 0).any()
    for t in range(1, looked.shape[0]):
        before = ep.track_label[ep.track_step == t - 1]      # the tracker's order
        for i in range(looked.shape[1]):
            want = before[looked[t, i]] if 0 <= looked[t, i] < len(before) else -1
            assert label[t, i] == want
            if want >= 0:
                assert want in set(mine_tracks.loc[mine_tracks["step"] == t - 1, "label"])


def test_a_study_of_the_previous_layout_is_read(search_dir: Path, tmp_path: Path) -> None:
    """A sensorplan-study/3 directory (no sensors.label) is read by report and replay, and
    refused for resuming."""
    import hashlib
    import json
    import shutil

    import pyarrow.parquet as pq

    from sensorplan import study as studies
    from sensorplan.errors import ConfigError
    from sensorplan.study.replay import replay_run

    old = tmp_path / "old"
    shutil.copytree(search_dir, old)
    config = json.loads((old / "config.resolved.json").read_text())
    config["format"] = "sensorplan-study/3"
    (old / "config.resolved.json").write_text(json.dumps(config))
    table = pq.read_table(old / "sensors.parquet").drop(["label"])
    pq.write_table(table, old / "sensors.parquet")
    sums = json.loads((old / "tables.sha256").read_text())
    sums["sensors"] = hashlib.sha256((old / "sensors.parquet").read_bytes()).hexdigest()
    (old / "tables.sha256").write_text(json.dumps(sums))
    t = studies.load_study_dir(old)
    assert t.complete and (t.sensors["label"] == -1).all()          # pmb: no label known
    assert replay_run(old, 0, "pmb").reproduced
    with pytest.raises(ConfigError) as info:
        studies.run_study(_search_study(), old, workers=1)
    assert info.value.field == "--out" and "sensorplan-study/3" in info.value.message


def test_the_decisions_table_holds_each_searching_plans_mu(tmp_path: Path) -> None:
    """With search on, each decision's mu and w mu as the episode recorded them (the
    replay's, an independent run of the same seed); with search off, nulls."""
    from sensorplan import study as studies
    from sensorplan.study.replay import replay_run

    base = _search_study()
    on = dataclasses.replace(base.methods[0].settings, search="on", search_sectors=6, steps=8)
    off = dataclasses.replace(base.methods[0].settings, steps=8)
    study = dataclasses.replace(base, runs=1, steps=8, methods=(
        studies.Method("search", on), studies.Method("track-only", off)))
    out = tmp_path / "study"
    studies.run_study(study, out, workers=1)
    d = pd.read_parquet(out / "decisions.parquet")
    searched = d[d["method"] == "search"].sort_values("decision")
    ep = replay_run(out, 0, "search").episode
    np.testing.assert_array_equal(searched["mu"].to_numpy(), ep.search_found)
    np.testing.assert_array_equal(searched["search_term"].to_numpy(), ep.search_term)
    assert (searched["mu"] > 0).any() and (searched["search_term"] >= 0).all()
    assert d.loc[d["method"] == "track-only", ["mu", "search_term"]].isna().all().all()
