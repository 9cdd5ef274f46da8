"""Plotting smoke test: a run's figure is written as a readable PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def test_plot_episode_writes_a_png(tmp_path: Path) -> None:
    from matplotlib.image import imread

    from sensorplan.config import load_simulation
    from sensorplan.figures.run import plot_episode
    from sensorplan.simulation import run_episode

    cfg = load_simulation(ROOT / "configs" / "quick.toml", overrides={"steps": 6})
    episode = run_episode(cfg.scenario, cfg.settings, cfg.seed)
    path = plot_episode(episode, cfg.scenario, tmp_path / "run.png")
    assert path == tmp_path / "run.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 400 and image.shape[1] > 400
    # Not a blank canvas: tracks and fields of view put many distinct colours on it.
    assert len(np.unique(image.reshape(-1, image.shape[2]), axis=0)) > 50
