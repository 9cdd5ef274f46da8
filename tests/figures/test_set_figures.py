"""Figures and animation of a run where targets are born and die and a multi-target tracker
confirms and deletes tracks: the events are those of the recorded arrays (counted here by
plain loops), and the figure draws one marker per event, each target only over its life and
each track with a width that grows with its existence."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

STEPS = 25


@pytest.fixture(scope="module")
def search_run():
    from sensorplan.simulation import run_episode
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import RunSettings, TrackerSettings

    # More births than the preset's and a survival below 1: a short run has both; the
    # tracker's birth and survival model is the truth's.
    scenario = dataclasses.replace(search_scenario(), look_detects="all", birth_rate=0.25,
                                   survival_probability=0.97)
    tracker = TrackerSettings(kind="pmb", birth_rate=0.25, survival_probability=0.97)
    settings = RunSettings(planner="pg", steps=STEPS, tracker=tracker)
    return scenario, run_episode(scenario, settings, 20261203)


def loop_events(ep) -> dict[str, set[tuple[int, int]]]:
    """(step, id) of every event, by plain loops over the recorded arrays."""
    alive = ep.alive
    S1, M = alive.shape
    out: dict[str, set[tuple[int, int]]] = {k: set() for k in
                                            ("births", "deaths", "confirmations", "deletions")}
    for j in range(M):
        for t in range(1, S1):
            if alive[t, j] and not alive[t - 1, j]:
                out["births"].add((t, j))
            if alive[t - 1, j] and not alive[t, j]:
                out["deaths"].add((t, j))
    reported: dict[int, list[int]] = {}
    for step, label in zip(ep.track_step.tolist(), ep.track_label.tolist()):
        reported.setdefault(label, []).append(step)
    for label, steps in reported.items():
        if min(steps) >= 1:
            out["confirmations"].add((min(steps), label))
        if max(steps) < S1 - 1:
            out["deletions"].add((max(steps) + 1, label))
    return out


def test_events_are_those_of_the_recorded_arrays(search_run) -> None:
    from sensorplan.study.lifespan import episode_events

    _, ep = search_run
    expected = loop_events(ep)
    events = episode_events(ep)
    for name, want in expected.items():
        got = getattr(events, name)
        assert set(zip(got.step.tolist(), got.ident.tolist())) == want, name
        assert len(got) == len(want)
    # the run has every kind of event
    assert all(expected.values()), {k: len(v) for k, v in expected.items()}
    # positions: a birth where the target first is, a death where it last was
    for t, j, xy in zip(events.births.step, events.births.ident, events.births.xy):
        np.testing.assert_array_equal(xy, ep.truth[t, j, :2])
    for t, j, xy in zip(events.deaths.step, events.deaths.ident, events.deaths.xy):
        np.testing.assert_array_equal(xy, ep.truth[t - 1, j, :2])
    for t, label, xy in zip(events.deletions.step, events.deletions.ident,
                            events.deletions.xy):
        row = np.flatnonzero((ep.track_step == t - 1) & (ep.track_label == label))
        np.testing.assert_array_equal(xy, ep.track_mean[row[0], :2])
    # the text of a step names exactly its events
    t = int(events.births.step[0])
    assert f"born T{int(events.births.ident[0])}" in events.text(t)
    quiet = next(s for s in range(1, STEPS + 1)
                 if not any(s == e[0] for v in expected.values() for e in v))
    assert events.text(quiet) == ""


def _gid(ax, gid: str) -> list:
    return [a for a in ax.get_children() if a.get_gid() == gid]


def test_set_figure_draws_every_event_and_lives_only(search_run, tmp_path: Path) -> None:
    from sensorplan.figures.run import episode_figure, plot_episode
    from sensorplan.figures.sets import track_width

    scenario, ep = search_run
    expected = loop_events(ep)
    fig = episode_figure(ep, scenario)
    ax = fig.axes[0]
    for name, want in expected.items():
        (markers,) = _gid(ax, name)
        assert len(markers.get_offsets()) == len(want), name
    # the true paths join consecutive live steps only
    (paths,) = _gid(ax, "true paths")
    live_pairs = int((ep.alive[1:] & ep.alive[:-1]).sum())
    assert len(paths.get_segments()) == live_pairs
    # tracks: one segment per pair of consecutive reports of a label, its width from r
    pairs, widths = 0, []
    rows = {(s, lab): k for k, (s, lab) in enumerate(zip(ep.track_step.tolist(),
                                                          ep.track_label.tolist()))}
    for (s, lab), k in rows.items():
        if (s - 1, lab) in rows:
            pairs += 1
            widths.append(0.4 + 2.6 * ep.track_existence[k])
    drawn = _gid(ax, "tracks") + _gid(ax, "false tracks")
    assert sum(len(c.get_segments()) for c in drawn) == pairs
    got = np.sort(np.concatenate([np.broadcast_to(c.get_linewidths(),
                                                  (len(c.get_segments()),)) for c in drawn]))
    np.testing.assert_allclose(got, np.sort(widths), rtol=1e-12)
    np.testing.assert_allclose(track_width([0.0, 0.5, 1.0]), [0.4, 1.7, 3.0])
    # the legend explains the markers and the widths
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"target born ({len(expected['births'])})" in texts
    assert any("existence r = 1" in t for t in texts)
    assert plot_episode(ep, scenario, tmp_path / "sets.png").stat().st_size > 10_000


def test_false_tracks_are_those_assigned_to_no_target(search_run) -> None:
    """Each track row's target is the one GOSPA assigns (independent brute force here)."""
    import itertools

    from sensorplan.study.lifespan import track_targets

    _, ep = search_run
    got = track_targets(ep, 50.0)
    checked = 0
    for t in range(ep.alive.shape[0]):
        rows = np.flatnonzero(ep.track_step == t)
        live = np.flatnonzero(ep.alive[t])
        if len(rows) > 6 or len(live) > 7 or not len(rows):
            continue
        best, pick = np.inf, None
        for perm in itertools.permutations(list(live) + [-1] * len(rows), len(rows)):
            cost, k = 0.0, 0
            for r, j in zip(rows, perm):
                d2 = (np.sum((ep.track_mean[r, :2] - ep.truth[t, j, :2]) ** 2)
                      if j >= 0 else np.inf)
                if d2 < 2500.0:
                    cost += d2
                    k += 1
            cost += 1250.0 * (len(rows) + len(live) - 2 * k)
            if cost < best - 1e-9:
                best, pick = cost, [j if j >= 0 and np.sum(
                    (ep.track_mean[r, :2] - ep.truth[t, j, :2]) ** 2) < 2500.0 else -1
                    for r, j in zip(rows, perm)]
        assert got[rows].tolist() == pick, t
        checked += 1
    assert checked > STEPS // 2


def test_animation_shows_the_events(search_run, tmp_path: Path) -> None:
    from sensorplan.figures.animation import _Frames, animate_episode
    from sensorplan.study.lifespan import episode_events

    scenario, ep = search_run
    events = episode_events(ep)
    frames = _Frames(ep, scenario, 12.0, 40)
    t = int(events.deaths.step[0])
    frames.render(t)
    title = frames.title.get_text()
    assert f"died T{int(events.deaths.ident[0])}" in title
    (layer,) = [g for g in frames.dense if hasattr(g, "log")]
    assert events.text(t) in layer.log.get_text()
    # markers of the step's events are shown, those of later steps not yet
    shown = layer.events["deaths"].get_offsets()
    later = events.deaths.xy[events.deaths.step > t]
    assert any(np.allclose(p, events.deaths.xy[0]) for p in shown)
    assert not any(np.allclose(p, q) for p in shown for q in later)
    # a frame shows exactly the tracks reported at its step, labelled with r
    rows = np.flatnonzero(ep.track_step == t)
    names = [n.get_text() for n in layer.names if n.get_visible()]
    assert sorted(names) == sorted(f"L{ep.track_label[k]}  r = {ep.track_existence[k]:.2f}"
                                   for k in rows)
    path = animate_episode(ep, scenario, tmp_path / "sets.gif", every=5, dpi=30)
    from PIL import Image

    with Image.open(path) as im:
        assert im.n_frames == len(range(0, STEPS + 1, 5))


def test_a_run_with_no_target_and_no_track_draws(tmp_path: Path) -> None:
    from sensorplan.figures.animation import animate_episode
    from sensorplan.figures.run import episode_figure
    from sensorplan.simulation import run_episode
    from sensorplan.simulation.scenario import search_scenario
    from sensorplan.simulation.settings import RunSettings, TrackerSettings

    scenario = dataclasses.replace(search_scenario(), look_detects="all", initial_targets=0,
                                   birth_rate=1e-9)
    ep = run_episode(scenario, RunSettings(planner="pg", steps=3,
                                           tracker=TrackerSettings(kind="pmb")), 1)
    assert not ep.alive.any() and len(ep.track_step) == 0
    ax = episode_figure(ep, scenario).axes[0]
    for name in ("births", "deaths", "confirmations", "deletions"):
        (markers,) = _gid(ax, name)
        assert len(markers.get_offsets()) == 0
    assert animate_episode(ep, scenario, tmp_path / "empty.gif", dpi=30).exists()
