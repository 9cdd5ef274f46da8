"""The run figure at both ends of its size range: small runs draw exactly as before the
swarm-scale drawing existed, and a swarm-size run draws its panels in the condensed form."""

from __future__ import annotations

import hashlib
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1] / "data"


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
    from sensorplan.figures.run import plot_episode
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


# ------------------------------------------------------------------- swarm size


@pytest.fixture(scope="module")
def swarm_run():
    """The swarm preset (100 sensors, 200 targets), 5 steps."""
    from sensorplan.config import load_simulation
    from sensorplan.simulation import run_episode

    cfg = load_simulation(preset="swarm", overrides={"steps": 5})
    return cfg, run_episode(cfg.scenario, cfg.settings, cfg.seed)


def _by_gid(ax, gid: str) -> list:
    return [a for a in ax.get_children() if a.get_gid() == gid]


def _semi_axes(C: np.ndarray) -> np.ndarray:
    """Semi-axes ``(K, 2)`` (major, minor) of the N_SIGMA ellipses of ``C (K, 2, 2)``, from
    the closed-form eigenvalues of a symmetric 2x2 matrix."""
    from sensorplan.figures.run import N_SIGMA

    a, b, d = C[:, 0, 0], 0.5 * (C[:, 0, 1] + C[:, 1, 0]), C[:, 1, 1]
    r = np.sqrt((0.5 * (a - d)) ** 2 + b ** 2)
    return N_SIGMA * np.sqrt(np.stack([0.5 * (a + d) + r, 0.5 * (a + d) - r], axis=1))


def test_swarm_figure_is_condensed(swarm_run, tmp_path: Path) -> None:
    """At 100 sensors and 200 targets the figure has its three panels, each kind of thing
    drawn once for all (not an artist per sensor or target), with the right geometry."""
    from matplotlib.image import AxesImage

    from sensorplan.figures import colors
    from sensorplan.figures.run import episode_figure, plot_episode

    cfg, ep = swarm_run
    S, N, M = ep.looked.shape[0] - 1, ep.looked.shape[1], ep.truth.shape[1]
    assert (N, M) == (100, 200)
    fig = episode_figure(ep, cfg.scenario)
    assert len(fig.axes) == 3
    ax_map, ax_time, ax_err = fig.axes
    assert len(ax_map.get_children()) < 60          # a few collections, not thousands
    # Fields of view at the last step: N wedges, each within its sensor's range band.
    (fov,) = _by_gid(ax_map, "fields of view")
    assert len(fov.get_paths()) == N
    for i, path in enumerate(fov.get_paths()):
        p = cfg.scenario.sensors[i].params
        (outline,) = path.to_polygons()                   # arcs flattened to points on them
        rel = outline - ep.sensor_positions[S, i]
        d = np.hypot(*rel.T)
        assert np.isclose(d.min(), p.min_ground_range, rtol=1e-3)
        assert np.isclose(d.max(), p.max_ground_range, rtol=1e-3)
        off = np.angle(np.exp(1j * (np.arctan2(rel[:, 1], rel[:, 0])
                                    - ep.sensor_headings[S, i])))
        assert np.abs(off).max() <= p.fov_half_angle + 1e-6
        assert np.isclose(np.abs(off).max(), p.fov_half_angle, atol=1e-6)
    # Looks at the last step: sensor -> the true position of the target it looked at.
    (looks,) = _by_gid(ax_map, "looks")
    i = np.nonzero(ep.looked[S] >= 0)[0]
    segs = np.asarray(looks.get_segments())
    np.testing.assert_allclose(segs[:, 0], ep.sensor_positions[S, i])
    np.testing.assert_allclose(segs[:, 1], ep.truth[S, ep.looked[S, i], :2])
    # Ellipses at the last step, centred on the estimates, axes from the covariances.
    (ell,) = _by_gid(ax_map, "ellipses")
    np.testing.assert_allclose(ell.get_offsets(), ep.estimate[S, :, :2])
    np.testing.assert_allclose(np.stack([ell._widths, ell._heights], axis=1),
                               _semi_axes(ep.cov[S, :, :2, :2]), rtol=1e-9)
    # Every missed look is marked on the target's true track.
    (crosses,) = _by_gid(ax_map, "missed looks")
    assert len(crosses.get_offsets()) == (ep.missed[1:] & (ep.looked[1:] >= 0)).sum() > 0
    # Tracks: one collection, S segments per target.
    (tracks,) = _by_gid(ax_map, "tracks")
    assert len(tracks.get_segments()) == M * S
    # Timeline: one image, cell (i, t - 1) in the colour of the target looked at in step t
    # (a white-mixed tint when the look missed).
    (image,) = [a for a in ax_time.get_children() if isinstance(a, AxesImage)]
    cells = np.asarray(image.get_array())
    assert cells.shape == (N, S, 3)
    for t in range(1, S + 1):
        for s in range(N):
            j, miss = ep.looked[t, s], ep.missed[t, s]
            want = (1.0, 1.0, 1.0) if j < 0 else colors.mix(colors.target_color(j),
                                                           0.45 if miss else 1.0)
            np.testing.assert_allclose(cells[s, t - 1], want)
    # Errors: one collection of M lines (error clipped below at 0.1 m) plus the medians.
    (errors,) = _by_gid(ax_err, "errors")
    lines = errors.get_segments()
    assert len(lines) == M
    np.testing.assert_allclose(lines[7][:, 1], np.clip(ep.error[:, 7], 0.1, None))
    # Legend and title summarise instead of listing 300 names and 200 numbers.
    texts = [t.get_text() for t in ax_map.get_legend().get_texts()]
    assert len(texts) < 15
    assert texts[0].startswith("T0\u2013T199") and texts[1].startswith("S0\u2013S99")
    assert "median" in ax_map.get_title() and len(ax_map.get_title()) < 120
    # The written figure stays a readable size.
    from PIL import Image

    with Image.open(plot_episode(ep, cfg.scenario, tmp_path / "swarm.png")) as im:
        assert 1000 < im.height < 2000 and 1000 < im.width < 2000


def _first(cfg, ep, n_sensors: int, n_targets: int):
    """The run restricted to its first sensors and targets (looks at dropped targets
    become no look): a smaller run to draw."""
    import dataclasses

    keep = ep.looked[:, :n_sensors] < n_targets
    looked = np.where(keep, ep.looked[:, :n_sensors], -1)
    small = dataclasses.replace(
        ep, looked=looked, missed=ep.missed[:, :n_sensors] & keep,
        false_alarms=ep.false_alarms[:, :n_sensors],
        sensor_positions=ep.sensor_positions[:, :n_sensors],
        sensor_headings=ep.sensor_headings[:, :n_sensors],
        truth=ep.truth[:, :n_targets], estimate=ep.estimate[:, :n_targets],
        cov=ep.cov[:, :n_targets], error=ep.error[:, :n_targets],
        target_kinds=ep.target_kinds[:n_targets])
    scenario = dataclasses.replace(cfg.scenario, sensors=cfg.scenario.sensors[:n_sensors],
                                   targets=cfg.scenario.targets[:n_targets])
    return small, scenario


@pytest.mark.parametrize("extra", [0, 1])
def test_condensed_drawing_starts_above_the_thresholds(swarm_run, extra: int) -> None:
    """Up to DENSE_SENSORS sensors (DENSE_TARGETS targets) each has its own artists; one
    more and they are drawn condensed."""
    from matplotlib.image import AxesImage
    from matplotlib.lines import Line2D

    from sensorplan.figures.run import DENSE_SENSORS, DENSE_TARGETS, episode_figure, look_runs

    cfg, ep = swarm_run
    n, m = DENSE_SENSORS + extra, DENSE_TARGETS + extra
    small, scenario = _first(cfg, ep, n, m)
    ax_map, ax_time, ax_err = episode_figure(small, scenario).axes
    images = [a for a in ax_time.get_children() if isinstance(a, AxesImage)]
    bars = [c for c in ax_time.collections if (c.get_gid() or "").startswith("look ")]
    names = {t.get_text() for t in ax_map.texts}
    error_lines = [ln for ln in ax_err.lines if len(ln.get_xdata()) == small.error.shape[0]]
    if extra:
        assert len(images) == 1 and not bars
        assert not names & {"S0", "T0"}
        assert len(_by_gid(ax_err, "errors")) == 1 and len(error_lines) == 2   # the medians
    else:
        assert not images and len(bars) == len(look_runs(small.looked, small.missed))
        assert {f"S{i}" for i in range(n)} | {f"T{j}" for j in range(m)} <= names
        assert not _by_gid(ax_err, "errors") and len(error_lines) == 2 * m
        assert all(isinstance(ln, Line2D) for ln in error_lines)


@pytest.mark.parametrize("m", [12, 13])
def test_legend_lists_targets_up_to_legend_items(swarm_run, m: int) -> None:
    from sensorplan.figures.run import LEGEND_ITEMS, episode_figure

    cfg, ep = swarm_run
    small, scenario = _first(cfg, ep, 5, m)
    ax_map = episode_figure(small, scenario).axes[0]
    texts = [t.get_text() for t in ax_map.get_legend().get_texts()]
    title = ax_map.get_title()
    if m <= LEGEND_ITEMS:
        assert texts[:m] == [f"T{j} ({k})" for j, k in enumerate(small.target_kinds)]
        assert title.count(",") >= m                       # every target's RMSE
    else:
        assert texts[0].startswith(f"T0\u2013T{m - 1} (") and not any(
            t.startswith("T1 ") for t in texts)
        assert "median" in title
    assert [t for t in texts if t.startswith("S")] == [
        f"S{i}, z = {float(s.params.altitude):g} m" for i, s in enumerate(scenario.sensors)]


def test_swarm_animation_moves_collections(swarm_run, tmp_path: Path) -> None:
    """At swarm size the animation's moving artists are a few collections; each frame puts
    the looks, positions and ellipses of its own step."""
    from sensorplan.figures.animation import _Frames, animate_episode

    cfg, ep = swarm_run
    S = ep.looked.shape[0] - 1
    frames = _Frames(ep, cfg.scenario, tail=12.0, dpi=30)
    assert not frames.track and not frames.fov and len(frames.dense) == 2
    sensors, targets = frames.dense
    images = []
    for t in (1, S):
        images.append(frames.render(t))
        i = np.nonzero(ep.looked[t] >= 0)[0]
        segs = np.asarray(sensors.look.get_segments())
        np.testing.assert_allclose(segs[:, 1], ep.truth[t, ep.looked[t, i], :2])
        np.testing.assert_allclose(targets.now.get_offsets(), ep.truth[t, :, :2])
        np.testing.assert_allclose(np.stack([targets.ell._widths, targets.ell._heights], 1),
                                   _semi_axes(ep.cov[t, :, :2, :2]), rtol=1e-9)
        missed = ep.missed[t, i]
        assert len(sensors.cross.get_offsets()) == missed.sum()
    assert np.any(images[0] != images[1])
    path = animate_episode(ep, cfg.scenario, tmp_path / "swarm.gif", dpi=30)
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        assert sum(1 for _ in ImageSequence.Iterator(im)) == S + 1


@pytest.mark.parametrize("t", [1, 5, 13, 40])
def test_faded_chunks_cover_each_path_once(t: int, rng: np.random.Generator) -> None:
    """The chunks of a path are its segments, each once, in tints that get lighter with
    age and stop at the oldest tint."""
    from sensorplan.figures.animation_swarm import FADE_CUTOFF, faded_chunks
    from sensorplan.figures.view import FADE_FLOOR

    K, tau = 3, 4.0
    xy = rng.normal(size=(t + 1, K, 2))
    rgb = rng.random((K, 3))
    lines, cols = faded_chunks(xy, rgb, t, tau)
    assert len(lines) == len(cols)
    seen = {k: [] for k in range(K)}
    for line, col in zip(lines, cols):
        k = int(np.nonzero([np.any(np.all(np.isclose(line[0], xy[:, kk]), axis=1))
                            for kk in range(K)])[0][0])
        first = int(np.nonzero(np.all(xy[:, k] == line[0], axis=1))[0][0])
        np.testing.assert_array_equal(line, xy[first:first + len(line), k])
        seen[k].append((first, first + len(line) - 1, col))
    oldest = FADE_FLOOR + (1 - FADE_FLOOR) * np.exp(-FADE_CUTOFF)
    for k, chunks in seen.items():
        chunks.sort(key=lambda c: c[0])
        assert chunks[0][0] == 0 and chunks[-1][1] == t
        assert all(a[1] == b[0] for a, b in itertools.pairwise(chunks))    # no gap or overlap
        # Tint weight: (colour - white) = w (rgb - white).
        w = [float(np.mean((c[2] - 1.0) / (rgb[k] - 1.0))) for c in chunks]
        assert all(a <= b + 1e-12 for a, b in itertools.pairwise(w))    # newer: stronger
        assert min(w) >= oldest - 1e-12 and max(w) <= 1.0


def test_ellipse_arrays_agree_with_ellipse_geometry(rng: np.random.Generator) -> None:
    from sensorplan.figures.run import ellipse_geometry
    from sensorplan.figures.swarm import ellipse_arrays

    A = rng.normal(size=(20, 2, 2)) * rng.uniform(0.1, 100, size=(20, 1, 1))
    C = A @ np.swapaxes(A, 1, 2)
    C[3] = np.diag([1e40, 1e38])
    C[4, 0, 0] = np.inf
    w, h, angle, ok = ellipse_arrays(C, limit=500.0)
    for k in range(len(C)):
        ref = ellipse_geometry(C[k], 500.0)
        assert ok[k] == (ref is not None)
        if ref is not None:
            np.testing.assert_allclose([w[k], h[k]], ref[:2], rtol=1e-9)
            # The major axis direction, up to a half turn.
            d = (angle[k] - ref[2]) % 180.0
            assert min(d, 180.0 - d) < 1e-6 or abs(ref[0] - ref[1]) < 1e-9 * ref[0]
