"""What search does, drawn: on a short run of the ``search`` preset with search on (no
target known at the start, so the few steps hold search looks and a find), the animation's
heat map shows the recorded intensity per km^2, a search look's hatched sector and ray
point where its sector's bearing says, finds are tracks confirmed inside a search look's
field of view (checked here with plain trigonometry), and the figures are written."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

STEPS = 15


@pytest.fixture(scope="module")
def search_run():
    from sensorplan.config import load_simulation
    from sensorplan.simulation.run import run_episode

    cfg = load_simulation(None, "search", {"search": "on", "steps": STEPS, "seed": 3})
    scenario = dataclasses.replace(cfg.scenario, initial_targets=0)
    # Edge births only (no background births), so that search looks go to the edges, where
    # the targets enter: 15 steps of seed 3 then hold a find to draw.
    tracker = dataclasses.replace(cfg.settings.tracker, background_birth_rate=0.0)
    settings = dataclasses.replace(cfg.settings, tracker=tracker)
    return scenario, run_episode(scenario, settings, cfg.seed)


def test_finds_are_confirmations_inside_a_search_look(search_run) -> None:
    from sensorplan.figures.search import search_finds

    scenario, ep = search_run
    finds = search_finds(ep, scenario)
    assert len(finds) >= 1
    first: dict[int, int] = {}
    for row, label in enumerate(ep.track_label.tolist()):
        first.setdefault(label, row)
    expected = set()
    for label, row in first.items():
        t = int(ep.track_step[row])
        if t < 1:
            continue
        x, y = ep.track_mean[row, :2]
        for i in range(ep.searched.shape[1]):
            if ep.searched[t, i] < 0:
                continue
            p = scenario.sensors[i].params
            sx, sy = ep.sensor_positions[t, i]
            r = math.hypot(x - sx, y - sy)
            off = (math.atan2(y - sy, x - sx) - ep.sensor_headings[t, i] + math.pi) \
                % (2 * math.pi) - math.pi
            if p.min_ground_range <= r <= p.max_ground_range and abs(off) <= p.fov_half_angle:
                expected.add((t, label, i))
                break
    assert set(zip(finds.step.tolist(), finds.label.tolist(), finds.sensor.tolist())) \
        == expected


def test_the_animation_draws_the_intensity_sectors_and_finds(search_run,
                                                             tmp_path: Path) -> None:
    from sensorplan.figures.animation import _Frames, animate_episode

    scenario, ep = search_run
    frames = _Frames(ep, scenario, 12.0, 60)
    layer = frames.search
    assert layer is not None and layer.heat is not None
    area_km2 = scenario.world.width * scenario.world.height / ep.undetected[0].size / 1e6
    n_sectors = int(ep.settings.search_sectors)
    searched_steps = np.flatnonzero((ep.searched[1:] >= 0).any(axis=1)) + 1
    assert len(searched_steps)
    for t in (int(searched_steps[0]), int(layer.view.finds.step[0]), STEPS):
        frames.draw(t)
        # Targets per km^2, one scale for the run: cells below a thousandth of its top
        # are left out.
        shown = np.ma.filled(layer.heat.get_array(), 0.0)
        want = ep.undetected[t].astype(float) / area_km2
        top = ep.undetected.max() / area_km2
        np.testing.assert_allclose(shown, np.where(want >= 1e-3 * top, want, 0.0), rtol=1e-6)
        for i, (wedge, _) in enumerate(layer.wedges):
            s = int(ep.searched[t, i])
            assert wedge.get_visible() == (s >= 0)
            if s < 0:
                continue
            # The sector is the beam at the look's heading; the ray the sector's bearing.
            mid = 0.5 * (wedge.theta1 + wedge.theta2)
            assert math.isclose(math.radians(mid), ep.sensor_headings[t, i], abs_tol=1e-9)
            (x0, x1), (y0, y1) = layer.rays[i].get_data()
            bearing = 2 * math.pi * s / n_sectors
            assert math.isclose(math.cos(math.atan2(y1 - y0, x1 - x0) - bearing), 1.0,
                                abs_tol=1e-9)
            assert f"{math.degrees(bearing) % 360:.0f}\u00b0" in layer.texts[i].get_text()
        # The title's mu is the search_found of the decision whose plan the step executes.
        k = list(ep.decision_steps).index(t - 1)       # a decision before every step here
        assert layer.view.mu[t] == ep.search_found[k]
        assert f"expects to find {ep.search_found[k]:.2f}" in layer.title(t)
        found = layer.view.finds.step == t
        np.testing.assert_array_equal(np.asarray(layer.found.get_offsets())[:found.sum()],
                                      layer.view.finds.xy[found])
    path = animate_episode(ep, scenario, tmp_path / "episode.gif", every=5)
    assert path.stat().st_size < 2_000_000


def test_the_static_figure_has_the_heat_map_and_a_run_without_intensity_has_none(
        search_run, tmp_path: Path) -> None:
    from sensorplan.figures.run import set_episode_figure

    scenario, ep = search_run
    fig = set_episode_figure(ep, scenario)
    maps = [im for ax in fig.axes for im in ax.images
            if im.get_gid() == "undetected intensity"]
    assert len(maps) == 1
    area_km2 = scenario.world.width * scenario.world.height / ep.undetected[0].size / 1e6
    last = ep.undetected[-1].astype(float) / area_km2
    top = ep.undetected.max() / area_km2
    np.testing.assert_allclose(np.ma.filled(maps[0].get_array(), 0.0),
                               np.where(last >= 1e-3 * top, last, 0.0), rtol=1e-6)
    plain = dataclasses.replace(ep, undetected=None, searched=None, search_found=None,
                                search_term=None)
    fig = set_episode_figure(plain, scenario)
    assert not [im for ax in fig.axes for im in ax.images
                if im.get_gid() == "undetected intensity"]
