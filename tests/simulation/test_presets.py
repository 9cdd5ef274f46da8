"""The search-and-track and benchmark presets: what they build, their scripted truths, and
that their detections have the detection probability and false-alarm rate they state."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorplan.config.simulate import load_simulation
from sensorplan.models.linear import benchmark_sensor, clutter_density
from sensorplan.models.scripted import BENCHMARKS, scripted_truth
from sensorplan.simulation.run import run_episode
from sensorplan.simulation.scan import cell_masses
from sensorplan.simulation.scenario import (PRESET_SETTINGS, PRESETS, RADAR_DETECTION,
                                            SEARCH_BIRTH_RATE)

#: Two-sided 99.9 % normal quantile: the statistical tests below fail by chance once in a
#: thousand seeds (their seeds are fixed).
Z = 3.2905


@pytest.mark.parametrize("name, steps, c", [("search", 200, 50.0), ("williams15", 81, 10.0),
                                            ("vo12", 100, 100.0)])
def test_each_preset_brings_its_tracker_length_and_gospa_cutoff(name, steps, c):
    cfg = load_simulation(preset=name)
    assert cfg.scenario == PRESETS[name]()
    assert cfg.settings.tracker.kind == "pmb"
    assert cfg.scenario.look_detects == "all"
    assert (cfg.settings.steps, cfg.settings.gospa_c) == (steps, c)
    # A given option replaces the preset's value.
    cfg = load_simulation(preset=name, overrides={"steps": 3, "gospa_c": 7.5})
    assert (cfg.settings.steps, cfg.settings.gospa_c) == (3, 7.5)


def test_the_urban_preset_brings_the_town_tracker_and_a_study_can_turn_it_off(tmp_path):
    """The town's tracker knows the buildings and has the lost-target mode (results.md,
    section 11.2); a file's or a study's tracker table replaces the preset's values."""
    from sensorplan.study.file import load_study

    cfg = load_simulation(preset="urban")
    assert cfg.settings.tracker.known_buildings and cfg.settings.tracker.lost_mode
    assert not load_simulation(preset="paper").settings.tracker.lost_mode
    f = tmp_path / "s.toml"
    f.write_text('runs = 1\nsteps = 2\nseed = 1\n[scenario]\npreset = "urban"\n'
                 '[defaults]\nplanner = "pg"\n[[methods]]\nname = "town"\n'
                 '[[methods]]\nname = "off"\n[methods.tracker]\nlost_mode = false\n')
    town, off = load_study(f).methods
    assert town.settings.tracker.lost_mode and town.settings.tracker.known_buildings
    assert not off.settings.tracker.lost_mode and off.settings.tracker.known_buildings
    ep = run_episode(PRESETS["urban"](), town.settings, 3)
    assert np.isfinite(ep.nees).all()


def test_the_search_preset():
    sc = PRESETS["search"]()
    assert (sc.births, sc.birth_rate, sc.n_initial, sc.survival_probability) == (
        "edges", SEARCH_BIRTH_RATE, 3, 1.0)
    assert all(s.params.detection == RADAR_DETECTION["detection"]
               and s.params.clutter_rate == RADAR_DETECTION["clutter_rate"] == 1.0
               for s in sc.sensors)
    assert sc.world.width == sc.world.height == 600.0 and len(sc.sensors) == 3
    assert "gospa_c" not in PRESET_SETTINGS["search"]["run"]           # the default 50 m
    # The tracker's births are the truth's, with background births on top.
    tracker = PRESET_SETTINGS["search"]["tracker"]
    assert (tracker["births"], tracker["birth_rate"]) == ("edges", SEARCH_BIRTH_RATE)
    assert tracker["background_birth_rate"] == 0.03


@pytest.mark.parametrize("name", ["williams15", "vo12"])
def test_the_scan_presets_have_their_benchmarks_map_and_sensor(name):
    sc = PRESETS[name]()
    bench = BENCHMARKS[name]
    assert sc.scan == sc.scripted == name and sc.sensors == ()
    assert (sc.world.width, sc.world.height, sc.dt) == (*bench.world_size, bench.dt)
    s = benchmark_sensor(name)
    assert s.area == (0.0, 0.0, *bench.world_size)
    assert (s.detection_probability, s.clutter_rate, s.noise_var) == {
        "williams15": (0.9, 10.0, 1.0), "vo12": (0.98, 30.0, 100.0)}[name]


def test_williams15_targets_coalesce_at_step_41_where_one_dies():
    truth = scripted_truth("williams15")
    positions, alive = [], []
    for t in range(1, 82):
        x, a = truth.step()
        assert truth.step_index == t
        positions.append(x[:, :2].copy())
        alive.append(a.copy())
    alive_ = np.array(alive)                                              # (81, 4)
    assert alive_.shape == (81, 4)
    # All four present for steps 1..40; target 0 absent from step 41 on, the others to 81.
    np.testing.assert_array_equal(alive_[:40], True)
    np.testing.assert_array_equal(alive_[40:, 0], False)
    np.testing.assert_array_equal(alive_[40:, 1:], True)
    # The live targets are closest together at step 41 (drawn from N(centre, 0.1 I) there:
    # within 2 m of the centre, over 6 standard deviations).
    P = np.array(positions)                                               # (81, 4, 2)
    spread = np.array([np.max(np.linalg.norm(P[k, alive_[k]] - P[k, alive_[k]].mean(0), axis=1))
                       for k in range(81)])
    assert int(np.argmin(spread)) + 1 == 41
    assert np.all(np.linalg.norm(P[40, 1:] - [150.0, 150.0], axis=1) < 2.0)
    # The dying target was there too: its last live state, one step before, is close by.
    assert np.linalg.norm(P[39, 0] - [150.0, 150.0]) < 5.0
    # ... and they separate away from it (the model's random walk in velocity).
    assert spread[0] > 5 * spread[40] and spread[-1] > 5 * spread[40]


def test_vo12_targets_are_born_at_steps_1_20_40_60_80():
    truth = scripted_truth("vo12")
    bench = BENCHMARKS["vo12"]
    born, alive, first = [], [], []
    for _ in range(1, 101):
        x, a = truth.step()
        first += [x[j, :2].copy() for j in range(len(first), len(a))]
        born.append(len(a))
        alive.append(int(a.sum()))
    born_ = np.array(born)
    new = np.diff(np.concatenate([[0], born_]))
    steps = np.flatnonzero(new) + 1
    np.testing.assert_array_equal(steps, [1, 20, 40, 60, 80])
    np.testing.assert_array_equal(new[steps - 1], [3, 3, 2, 2, 2])
    # Two of the first targets are last present at step 70.
    assert alive[69] - alive[70] == 2 and born_[-1] == 12 and alive[-1] == 10
    # Every target starts at one of the four birth sites and is seen after one step's move.
    start = bench.start
    site = np.linalg.norm(start[:, None, :2] - bench.birth_sites[None], axis=-1).min(axis=1)
    np.testing.assert_allclose(site, 0.0, atol=1e-9)
    np.testing.assert_allclose(first, start[:, :2] + bench.dt * start[:, 2:], atol=1e-9)


@pytest.mark.parametrize("name, seed", [("williams15", 41), ("vo12", 12)])
def test_a_scan_presets_detections_have_its_pd_and_false_alarm_rate(name, seed):
    """Over one run's scans: detected target-scans ~ Binomial(live target-scans, Pd), false
    alarms ~ Poisson(scans x rate). Each count must lie in its 99.9 % normal interval, and
    that interval must exclude the count a rate 20 % off would give (so the test has the
    power to catch it)."""
    cfg = load_simulation(preset=name)
    ep = run_episode(cfg.scenario, cfg.settings, seed)
    sensor = benchmark_sensor(name)
    live = int(ep.alive[1:].sum())
    detected = int(ep.measured[1:].sum())
    pd = sensor.detection_probability
    half = Z * math.sqrt(live * pd * (1 - pd))
    assert abs(detected - live * pd) <= half
    assert 0.2 * live * pd > half                      # 0.8 Pd would fail
    scans = cfg.settings.steps
    false = int(ep.false_alarms[1:].sum())
    lam = sensor.clutter_rate * scans
    assert abs(false - lam) <= Z * math.sqrt(lam)
    assert 0.2 * lam > Z * math.sqrt(lam)               # a rate 20 % off would fail
    # Every detection is a target's or a false alarm.
    assert int(ep.detections[1:].sum()) == detected + false


def test_the_scan_trackers_birth_intensity_is_the_sources_gaussians_on_the_grid():
    # One component in the middle of a 4 x 2 grid of 1 m cells: a closed form per cell.
    from scipy.stats import norm

    w = cell_masses(4.0, 2.0, 4, 2, np.array([[2.0, 1.0]]), np.array([[1.0, 0.5]]),
                    np.array([0.3]))
    px = np.diff(norm.cdf([0, 1, 2, 3, 4], loc=2.0, scale=1.0))
    py = np.diff(norm.cdf([0, 1, 2], loc=1.0, scale=0.5))
    np.testing.assert_allclose(w, 0.3 * np.outer(py, px).ravel(), rtol=1e-12)
    # vo12's four sites hold almost all of their 4 x 0.03 births per step on the map.
    bench = BENCHMARKS["vo12"]
    w = cell_masses(2000.0, 2000.0, 80, 80, bench.birth_sites,
                    np.tile(bench.birth_std[:2], (4, 1)), np.full(4, bench.birth_weight))
    np.testing.assert_allclose(w.sum(), 0.12, rtol=1e-9)
    assert clutter_density(benchmark_sensor("vo12")) == 30.0 / 2000.0 ** 2
