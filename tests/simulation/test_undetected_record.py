"""The episode's record of the undetected intensity: after every step it holds the tracker's
grid, cell by cell where the cell's centre lies (read here from the tracker itself through
a spy on its update), so its sum is the tracker's expected number of undetected targets;
trackers without an intensity record nothing and their files have no such entry."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

STEPS = 12


@pytest.fixture(scope="module")
def spied_run():
    """A short search run (the ``search`` preset with search on), and the tracker's own
    intensity after its construction and after each step's update. Without recycling, so
    that only births add to the intensity."""
    from sensorplan.config import load_simulation
    from sensorplan.simulation import run as run_module

    cfg = load_simulation(None, "search", {"search": "on", "steps": STEPS, "seed": 3})
    tracker = dataclasses.replace(cfg.settings.tracker, recycle_threshold=0.0)
    cfg = dataclasses.replace(cfg, settings=dataclasses.replace(cfg.settings, tracker=tracker))
    seen: list[tuple[np.ndarray, np.ndarray]] = []
    original = run_module.make_tracker

    def spy(*args, **kwargs):
        tracker = original(*args, **kwargs)
        update = tracker.update

        def spied_update(looks):
            out = update(looks)
            seen.append((np.array(tracker.undetected), np.array(tracker.grid.centres)))
            return out

        tracker.update = spied_update
        seen.append((np.array(tracker.undetected), np.array(tracker.grid.centres)))
        return tracker

    mp = pytest.MonkeyPatch()
    mp.setattr(run_module, "make_tracker", spy)
    try:
        episode = run_module.run_episode(cfg.scenario, cfg.settings, cfg.seed)
    finally:
        mp.undo()
    return cfg, episode, seen


def test_the_recorded_grid_is_the_trackers_after_every_step(spied_run) -> None:
    cfg, ep, seen = spied_run
    assert ep.undetected is not None and ep.undetected.dtype == np.float32
    assert len(seen) == STEPS + 1 == ep.undetected.shape[0]
    W, H = cfg.scenario.world.width, cfg.scenario.world.height
    ny, nx = ep.undetected.shape[1:]
    for t, (weights, centres) in enumerate(seen):
        # Each cell's weight where its centre lies: row from y, column from x.
        expected = np.zeros((ny, nx))
        for w, (cx, cy) in zip(weights, centres):
            expected[int(cy // (H / ny)), int(cx // (W / nx))] += w
        np.testing.assert_allclose(ep.undetected[t], expected, rtol=1e-6, atol=1e-12)
        # The sum is the tracker's expected number of undetected targets.
        np.testing.assert_allclose(ep.undetected[t].sum(dtype=np.float64), weights.sum(),
                                   rtol=1e-6)
    totals = np.array([w.sum() for w, _ in seen])
    assert totals[-1] > 0.0                         # births fed it
    # Predict adds at most the births, a look only thins.
    tr = cfg.settings.tracker
    births = tr.birth_rate + tr.background_birth_rate
    assert np.all(totals[1:] <= tr.survival_probability * totals[:-1] + births + 1e-12)


def test_the_grid_survives_the_file_and_other_trackers_record_none(spied_run,
                                                                   tmp_path: Path) -> None:
    from sensorplan.config import load_simulation
    from sensorplan.simulation.episode import Episode
    from sensorplan.simulation.run import intensity_grid_shape, run_episode

    cfg, ep, _ = spied_run
    assert ep.undetected.shape[1:] == intensity_grid_shape(cfg.scenario, cfg.settings.tracker)
    ep.save(tmp_path / "a.npz")
    back = Episode.load(tmp_path / "a.npz")
    np.testing.assert_array_equal(back.undetected, ep.undetected)
    known = load_simulation(None, "paper", {"steps": 3, "seed": 1})
    plain = run_episode(known.scenario, known.settings, known.seed)
    assert plain.undetected is None
    plain.save(tmp_path / "b.npz")
    with np.load(tmp_path / "b.npz") as data:
        assert "undetected" not in data.files
    # The entry costs what the docs say: 4 bytes a cell and step before compression.
    with np.load(tmp_path / "a.npz") as data:
        assert data["undetected"].nbytes == 4 * ep.undetected[0].size * (STEPS + 1)
