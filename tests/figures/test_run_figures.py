"""Pictures of a run: the static figure, the animation, the replay of a study's run, and
one colour scheme across them."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import assert_bad_input, run
from sensorplan.figures import colors
from sensorplan.config import load_simulation
from sensorplan.simulation import run_episode

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "configs" / "quick.toml"

#: Buildings, false alarms (a cluttered Swerling sensor) and misses, in 6 steps.
BUSY = """
[planning]
planner = "pg"
horizon = 2
steps_per_epoch = 2
[run]
steps = 6
seed = 3
[[targets]]
kind = "cv"
[[targets]]
kind = "dubins"
[[targets]]
kind = "cv"
[[sensors]]
altitude = 490.0
clutter_rate = 2.0
detection = "swerling1"
[[sensors]]
altitude = 510.0
[[buildings]]
box = [150.0, 150.0, 300.0, 220.0]
height = 40.0
[[buildings]]
box = [320.0, 300.0, 420.0, 450.0]
height = 60.0
"""


@pytest.fixture(scope="module")
def quick_run():
    cfg = load_simulation(QUICK, overrides={"steps": 6})
    return cfg, run_episode(cfg.scenario, cfg.settings, cfg.seed)


@pytest.fixture(scope="module")
def busy_run(tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("busy") / "busy.toml"
    path.write_text(BUSY)
    cfg = load_simulation(path)
    return cfg, run_episode(cfg.scenario, cfg.settings, cfg.seed)


# -------------------------------------------------------------------------- colours


def test_palettes_never_share_a_colour_between_meanings() -> None:
    targets = {c.lower() for c in colors.TARGET_PALETTE}
    sensors = {c.lower() for c in colors.SENSOR_GREYS}
    methods = {c.lower() for c in colors.METHOD_PALETTE}
    kinds = {c.lower() for c in colors.KIND_COLORS.values()}
    for palette, values in ((targets, colors.TARGET_PALETTE), (sensors, colors.SENSOR_GREYS),
                            (methods, colors.METHOD_PALETTE)):
        assert len(palette) == len(values)                  # no repeats inside a palette
    assert not targets & sensors
    assert not methods & kinds
    assert not kinds & {colors.MEAN_COLOR.lower(), colors.MEDIAN_COLOR.lower()}
    # Sensors are greys (r = g = b); no target colour is.
    for c in colors.SENSOR_GREYS:
        r, g, b = colors.mix(c, 1.0)
        assert r == g == b
    for c in colors.TARGET_PALETTE:
        r, g, b = colors.mix(c, 1.0)
        assert max(r, g, b) - min(r, g, b) > 0.2
    # The first 30 sensors have distinct (grey, marker) pairs.
    assert len({colors.sensor_style(i) for i in range(30)}) == 30


def test_mix_is_the_convex_combination_with_white() -> None:
    np.testing.assert_allclose(colors.mix("#000000", 0.25), (0.75, 0.75, 0.75))
    np.testing.assert_allclose(colors.mix("#ff0000", 1.0), (1.0, 0.0, 0.0))
    assert colors.mix_hex("#336699", 1.0) == "#336699"
    assert colors.mix_hex("#336699", 0.0) == "#ffffff"


# ------------------------------------------------------------------------- geometry


def test_ellipse_geometry_closed_forms() -> None:
    from sensorplan.figures.run import N_SIGMA, ellipse_geometry

    w, h, angle = ellipse_geometry(np.diag([100.0, 25.0]), limit=1e9)
    assert (w, h) == (2 * N_SIGMA * 10.0, 2 * N_SIGMA * 5.0)
    assert math.isclose(abs(angle) % 180, 0.0, abs_tol=1e-9)
    # Rotated by 30 degrees: R diag(100, 25) R^T has its major axis at 30 degrees.
    a = math.radians(30)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    w, h, angle = ellipse_geometry(R @ np.diag([100.0, 25.0]) @ R.T, limit=1e9)
    np.testing.assert_allclose([w, h], [4 * 10.0, 4 * 5.0], rtol=1e-12)
    assert math.isclose(angle % 180, 30.0, abs_tol=1e-9)
    # Huge covariances are clipped to the limit; non-finite ones are not drawn.
    w, h, _ = ellipse_geometry(np.diag([1e40, 1e38]), limit=1800.0)
    assert (w, h) == (3600.0, 3600.0)
    assert ellipse_geometry(np.diag([1e308, 1e308]), limit=1.0)[:2] == (2.0, 2.0)
    assert ellipse_geometry(np.array([[np.inf, 0], [0, 1.0]]), limit=1.0) is None


def test_look_runs_rebuild_the_looks_exactly(rng: np.random.Generator) -> None:
    from sensorplan.figures.run import look_runs

    S, N = 40, 3
    looked = np.full((S + 1, N), -1)
    looked[1:] = rng.integers(-1, 3, size=(S, N))
    missed = np.zeros((S + 1, N), dtype=bool)
    missed[1:] = (rng.random((S, N)) < 0.3) & (looked[1:] >= 0)
    rebuilt_target = np.full_like(looked, -1)
    rebuilt_missed = np.zeros_like(missed)
    runs = look_runs(looked, missed)
    for r in runs:
        assert 1 <= r.first <= r.last <= S
        sl = slice(r.first, r.last + 1)
        assert (rebuilt_target[sl, r.sensor] == -1).all()      # runs never overlap
        rebuilt_target[sl, r.sensor] = r.target
        rebuilt_missed[sl, r.sensor] = r.missed
    np.testing.assert_array_equal(rebuilt_target, looked)
    np.testing.assert_array_equal(rebuilt_missed, missed)
    # Runs are maximal: two runs of a sensor that touch differ in target or outcome.
    for a, b in zip(runs, runs[1:]):
        if a.sensor == b.sensor and a.last + 1 == b.first:
            assert (a.target, a.missed) != (b.target, b.missed)


# --------------------------------------------------------------------- static figure


def _hex(rgba) -> str:
    return "#" + "".join(f"{round(255 * v):02x}" for v in rgba[:3])


def test_static_figure_timeline_matches_the_looks(busy_run) -> None:
    from sensorplan.figures.run import MISS_HATCH, episode_figure

    cfg, episode = busy_run
    fig = episode_figure(episode, cfg.scenario)
    ax_map, ax_time, ax_err = fig.axes[:3]
    looked, missed = episode.looked, episode.missed
    S, N = looked.shape[0] - 1, looked.shape[1]
    dt = cfg.scenario.dt
    covered = np.full((S + 1, N), -1)
    was_missed = np.zeros((S + 1, N), dtype=bool)
    for coll in ax_time.collections:
        gid = coll.get_gid() or ""
        if not gid.startswith("look "):
            continue
        _, s, t, *rest = gid.split()
        i, j = int(s[1:]), int(t[1:])
        face = _hex(coll.get_facecolor()[0])
        if rest:                                            # a missed look: hatched tint
            assert coll.get_hatch() == MISS_HATCH
            assert face == colors.mix_hex(colors.target_color(j), 0.45)
        else:
            assert not coll.get_hatch()
            assert face == colors.target_color(j)
        for path in coll.get_paths():
            x0, x1 = path.vertices[:, 0].min(), path.vertices[:, 0].max()
            steps = np.arange(round(x0 / dt) + 1, round(x1 / dt) + 1)
            assert (covered[steps, i] == -1).all()
            covered[steps, i] = j
            was_missed[steps, i] = bool(rest)
    np.testing.assert_array_equal(covered[1:], looked[1:])
    np.testing.assert_array_equal(was_missed[1:], missed[1:])
    assert missed[1:].any() and episode.false_alarms[1:].any()   # the scenario shows both
    # Buildings are drawn and labelled with their height.
    texts = {t.get_text() for t in ax_map.texts}
    assert {"40 m", "60 m"} <= texts
    # One error line per target in its colour (the dotted ones are the filter's own).
    solid = [ln for ln in ax_err.lines if ln.get_linestyle() == "-"]
    assert [_hex(ln.get_color()) if not isinstance(ln.get_color(), str) else ln.get_color()
            for ln in solid[:3]] == colors.target_colors(3)


def test_plot_with_huge_covariances_clips_the_ellipses(quick_run, tmp_path: Path) -> None:
    from matplotlib.patches import Ellipse

    from sensorplan.figures.run import episode_figure, map_limit, plot_episode

    cfg, episode = quick_run
    huge = dataclasses.replace(episode, cov=episode.cov * 1e40)
    fig = episode_figure(huge, cfg.scenario)
    ellipses = [p for p in fig.axes[0].patches if isinstance(p, Ellipse)]
    assert ellipses
    assert max(max(e.width, e.height) for e in ellipses) <= 2 * map_limit(cfg.scenario)
    assert plot_episode(huge, cfg.scenario, tmp_path / "huge.png").stat().st_size > 10_000


# ------------------------------------------------------------------------- animation


def _frames(path: Path) -> list[np.ndarray]:
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        return [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]


@pytest.mark.parametrize("every", [1, 4])
def test_animation_has_one_frame_per_step_and_every_frame_moves(quick_run, tmp_path: Path,
                                                                every: int) -> None:
    from sensorplan.figures.animation import animate_episode, frame_steps

    cfg, episode = quick_run
    S = episode.error.shape[0] - 1
    path = animate_episode(episode, cfg.scenario, tmp_path / "run.gif", every=every, dpi=40)
    frames = _frames(path)
    # Pillow merges identical consecutive frames, so the count also shows they differ.
    expected = frame_steps(S, every)
    assert len(frames) == len(expected) == (S + 1 if every == 1 else 3)
    assert expected[0] == 0 and expected[-1] == S
    assert len({f.shape for f in frames}) == 1
    for a, b in zip(frames, frames[1:]):
        changed = np.any(a != b, axis=2).mean()
        assert changed > 0.001, changed


def test_animation_of_buildings_and_false_alarms(busy_run, tmp_path: Path) -> None:
    from sensorplan.figures.animation import _Frames

    cfg, episode = busy_run
    frames = _Frames(episode, cfg.scenario, tail=12.0, dpi=40)
    t = int(np.nonzero(episode.false_alarms[1:, 0])[0][0]) + 1
    frames.render(t)
    assert "false alarm" in frames.fa_text[0].get_text()
    assert frames.fa_text[0].get_text().strip().startswith(str(episode.false_alarms[t, 0]))
    # The look line of each sensor goes to the true position of its target, in its colour.
    for i in range(episode.looked.shape[1]):
        j = episode.looked[t, i]
        xs, ys = frames.look[i].get_data()
        np.testing.assert_allclose([xs[1], ys[1]], episode.truth[t, j, :2])
        assert frames.look[i].get_color() == colors.target_color(j)
        assert (frames.look[i].get_linestyle() == "--") == bool(episode.missed[t, i])


def test_mp4_needs_ffmpeg(quick_run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorplan.figures import animation
    cfg, episode = quick_run
    if animation.ffmpeg_available():
        import shutil
        import subprocess

        path = animation.animate_episode(episode, cfg.scenario, tmp_path / "run.mp4", dpi=40)
        assert path.stat().st_size > 1000
        if shutil.which("ffprobe"):
            probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-show_entries",
                                    "stream=codec_name,nb_read_frames", "-of", "csv=p=0",
                                    str(path)], capture_output=True, text=True, check=True)
            assert probe.stdout.strip() == f"h264,{episode.error.shape[0]}"
    monkeypatch.setattr(animation.shutil, "which", lambda name: None)
    with pytest.raises(ValueError, match="ffmpeg"):
        animation.animate_episode(episode, cfg.scenario, tmp_path / "run.mp4")


def test_simulate_animate_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                              monkeypatch: pytest.MonkeyPatch) -> None:
    code, out, err = run(capsys, "simulate", QUICK, "--steps", "4", "--animate", "--out",
                         tmp_path)
    assert code == 0, err
    assert len(_frames(tmp_path / "episode.gif")) == 5
    assert "episode.gif" in out
    assert_bad_input(run(capsys, "simulate", QUICK, "--steps", "4", "--animate",
                         "--animation-format", "avi", "--out", tmp_path / "x"),
                     "--animation-format")
    from sensorplan.figures import animation
    monkeypatch.setattr(animation.shutil, "which", lambda name: None)
    line = assert_bad_input(run(capsys, "simulate", QUICK, "--steps", "4", "--animate",
                                "--animation-format", "mp4", "--out", tmp_path / "y"),
                            "--animation-format")
    assert "ffmpeg" in line
    assert not (tmp_path / "y").exists()          # refused before anything is created


# ---------------------------------------------------------------------------- replay

STUDY = """
runs = 2
steps = 8
seed = 11
[defaults]
steps_per_epoch = 2
[[methods]]
name = "myopic"
planner = "pg"
[[methods]]
name = "OLF pg K=2"
planner = "pg"
horizon = 2
"""


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from sensorplan import study as studies

    out = tmp_path_factory.mktemp("replay") / "study"
    studies.run_study(studies.parse_study(STUDY), out, workers=1)
    return out


def test_replay_reproduces_the_stored_run_exactly(study_dir: Path) -> None:
    import pandas as pd

    from sensorplan.study.replay import replay_run

    rep = replay_run(study_dir, 1, "OLF pg K=2")
    assert rep.stored and rep.reproduced, rep.differences
    steps = pd.read_parquet(study_dir / "steps.parquet")
    mine = steps[(steps["run"] == 1) & (steps["method"] == "OLF pg K=2")]
    stored = mine.pivot(index="step", columns="target", values="error").to_numpy()
    np.testing.assert_array_equal(rep.episode.error, stored)
    sensors = pd.read_parquet(study_dir / "sensors.parquet")
    mine = sensors[(sensors["run"] == 1) & (sensors["method"] == "OLF pg K=2")]
    np.testing.assert_array_equal(
        rep.episode.looked, mine.pivot(index="step", columns="sensor", values="target"))
    # Another run of the same method is another trajectory.
    other = replay_run(study_dir, 0, "OLF pg K=2")
    assert not np.array_equal(other.episode.error, rep.episode.error)


def test_replay_notices_a_difference(study_dir: Path) -> None:
    import pandas as pd

    from sensorplan.study.replay import _compare, replay_run

    rep = replay_run(study_dir, 0, "myopic")
    steps = pd.read_parquet(study_dir / "steps.parquet")
    sensors = pd.read_parquet(study_dir / "sensors.parquet")
    steps = steps[(steps["run"] == 0) & (steps["method"] == "myopic")].copy()
    sensors = sensors[(sensors["run"] == 0) & (sensors["method"] == "myopic")]
    tracks = pd.read_parquet(study_dir / "tracks.parquet")
    tracks = tracks[(tracks["run"] == 0) & (tracks["method"] == "myopic")]
    assert set(_compare(rep.episode, steps, sensors, tracks).values()) == {0.0}
    steps.loc[steps.index[7], "error"] += 0.25
    diffs = _compare(rep.episode, steps, sensors, tracks)
    assert diffs["steps.error"] == pytest.approx(0.25)
    assert sum(v > 0 for v in diffs.values()) == 1


def test_replay_cli(study_dir: Path, tmp_path: Path,
                    capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    code, stdout, err = run(capsys, "replay", study_dir, "--run", "1", "--method", "myopic",
                            "--out", out)
    assert code == 0, err
    assert "identical to the stored run 1 of 'myopic'" in stdout
    assert len(_frames(out / "episode.gif")) == 9
    assert (out / "episode.png").exists() and (out / "episode.npz").exists()
    assert_bad_input(run(capsys, "replay", study_dir, "--run", "2", "--method", "myopic",
                         "--out", tmp_path / "a"), "--run")
    line = assert_bad_input(run(capsys, "replay", study_dir, "--run", "0", "--method",
                                "myopc", "--out", tmp_path / "b"), "--method")
    assert "did you mean 'myopic'" in line
    assert_bad_input(run(capsys, "replay", tmp_path, "--run", "0", "--method", "myopic"),
                     "DIR")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
