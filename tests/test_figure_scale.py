"""The run figure at both ends of its size range: small runs draw exactly as before the
swarm-scale drawing existed, and a swarm-size run draws its panels in the condensed form."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data"


def _pixels(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGBA"))


@pytest.mark.parametrize("name", ["paper", "busy"])
def test_small_figure_is_pixel_identical_to_the_reference(name: str, tmp_path: Path) -> None:
    """The figure of a stored small run (the paper preset; a run with buildings, misses and
    false alarms) has exactly the pixels it had before the swarm-scale drawing was added
    (tests/data/README.md says how the hashes were written)."""
    import matplotlib

    from sensorplan.config import load_simulation
    from sensorplan.plotting import plot_episode
    from sensorplan.simulation import Episode

    golden = json.loads((DATA / "figure_golden.json").read_text())
    if matplotlib.__version__ != golden["matplotlib"]:
        pytest.skip(f"reference pixels are of matplotlib {golden['matplotlib']}")
    episode = Episode.load(DATA / f"figure_{name}_episode.npz")
    if name == "paper":
        scenario = load_simulation(preset="paper").scenario
    else:
        scenario = load_simulation(DATA / "figure_busy.toml").scenario
    if name == "busy":      # the reference shows every element of the timeline
        assert episode.missed[1:].any() and episode.false_alarms[1:].any()
        assert scenario.buildings
    px = _pixels(plot_episode(episode, scenario, tmp_path / f"{name}.png"))
    assert list(px.shape) == golden[name]["shape"]
    assert hashlib.sha256(px.tobytes()).hexdigest() == golden[name]["sha256"]
