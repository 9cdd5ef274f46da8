"""Grid studies: cell expansion, the features, validation, running and resuming across
cells, the report's heat-map numbers against a second computation, the shipped grid."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sensorplan import study as studies
from sensorplan.errors import ConfigError
from sensorplan.report import write_report
from sensorplan.report.grid_figures import NOT_RUN, heatmap_panels, heatmap_values
from sensorplan.simulation.scenario import town_buildings
from sensorplan.study.grid import Axis, cell_indices, cell_slug, grid_from_dict, load_grid
from sensorplan.study.grid_run import GridInterrupted, grid_statistics, run_grid

from cli_helpers import assert_bad_input, run

ROOT = Path(__file__).resolve().parents[2]

#: Cheap methods (random and myopic pg), two axes of two values: 3 star cells.
HEAD = """\
description = "tiny grid"
runs = 2
steps = 6
seed = 3
[defaults]
planner = "pg"
[[methods]]
name = "random"
planner = "random"
[[methods]]
name = "myopic"
[[methods]]
name = "olf2"
horizon = 2
"""
AXES = """\
[[axes]]
feature = "sensor_speed"
values = [0.5, 1.0]
base = 1.0
[[axes]]
feature = "clutter_rate"
values = [0, 1]
base = 0
"""
COMPARISONS = """\
[[comparisons]]
method = "myopic"
reference = "random"
[[comparisons]]
method = "olf2"
reference = "myopic"
label = "K = 2 vs myopic"
"""
GOOD = HEAD + AXES + COMPARISONS


def parse(text: str) -> Any:
    import tomllib

    return grid_from_dict(tomllib.loads(text))


# ------------------------------------------------------------------------ expansion


AXIS_SETS = [
    [("a", [1, 2, 3], 2)],
    [("a", [1, 2, 3], 1), ("b", [0.5, 1.0], 1.0)],
    [("a", [1, 2], 1), ("b", [0.25, 0.5, 0.75, 1.0], 0.5), ("c", ["x", "y", "z"], "z")],
]


@pytest.mark.parametrize("spec", AXIS_SETS)
def test_star_cells_are_the_base_plus_one_per_other_value(spec: list[Any]) -> None:
    axes = tuple(Axis("setting", tuple(v), b, key=n) for n, v, b in spec)
    idx = cell_indices(axes, "star")
    assert len(idx) == 1 + sum(len(v) - 1 for _, v, _ in spec)
    slugs = [cell_slug(axes, i, "star") for i in idx]
    text = {1: "1", 2: "2", 3: "3", 0.25: "0.25", 0.5: "0.5", 0.75: "0.75"}   # 1.0 -> "1"
    expected = ["base"] + [f"{n}={text.get(x, x)}" for n, v, b in spec for x in v if x != b]
    assert slugs == expected
    # Every cell is the base with at most one axis moved.
    base = idx[0]
    assert all(sum(k != b for k, b in zip(i, base)) == (0 if s == "base" else 1)
               for i, s in zip(idx, slugs))


@pytest.mark.parametrize("spec", AXIS_SETS)
def test_full_cells_are_the_cartesian_product(spec: list[Any]) -> None:
    axes = tuple(Axis("setting", tuple(v), None, key=n) for n, v, _ in spec)
    idx = cell_indices(axes, "full")
    assert len(idx) == math.prod(len(v) for _, v, _ in spec)
    assert sorted(idx) == sorted(itertools.product(*(range(len(v)) for _, v, _ in spec)))
    slugs = [cell_slug(axes, i, "full") for i in idx]
    assert len(set(slugs)) == len(slugs)
    first = ",".join(f"{n}={Axis('setting', tuple(v), key=n).labels[0]}" for n, v, _ in spec)
    assert slugs[0] == first


def test_grid_cells_share_runs_steps_seed_and_methods() -> None:
    grid = parse(GOOD)
    assert [c.slug for c in grid.cells] == ["base", "sensor_speed=0.5", "clutter_rate=1"]
    for c in grid.cells:
        s = c.study
        assert (s.runs, s.steps, s.seed) == (2, 6, 3)
        assert [m.to_dict() for m in s.methods] == [m.to_dict() for m in grid.study.methods]
        assert "grid cell " + c.slug in s.description
    full = parse(GOOD.replace('description = "tiny grid"', 'design = "full"'))
    assert [c.slug for c in full.cells] == [
        "sensor_speed=0.5,clutter_rate=0", "sensor_speed=0.5,clutter_rate=1",
        "sensor_speed=1,clutter_rate=0", "sensor_speed=1,clutter_rate=1"]


# ------------------------------------------------------------------------- features


def _one_axis(feature: str, values: str, base: str, preset: str = "paper") -> str:
    return (HEAD + f'[scenario]\npreset = "{preset}"\n[[axes]]\nfeature = "{feature}"\n'
            f"values = {values}\nbase = {base}\n")


def _cell(grid: Any, slug: str) -> Any:
    return next(c for c in grid.cells if c.slug == slug).study.scenario


def _with_params(scenario: Any, **params: Any) -> Any:
    sensors = tuple(dataclasses.replace(s, params=dataclasses.replace(s.params, **params))
                    for s in scenario.sensors)
    return dataclasses.replace(scenario, sensors=sensors)


def test_sensor_speed_scales_every_sensors_moves() -> None:
    grid = parse(_one_axis("sensor_speed", "[0.25, 1.0]", "1.0"))
    base = grid.study.scenario
    assert _cell(grid, "base") == base                     # x 1 keeps the paper's moves
    assert _cell(grid, "sensor_speed=0.25") == _with_params(base, moves=(5.0, 10.0))


def test_min_ground_range_sets_every_sensors_blind_disc() -> None:
    grid = parse(_one_axis("min_ground_range", "[150, 250]", "250"))
    base = grid.study.scenario
    cell = _cell(grid, "min_ground_range=150")
    assert cell == _with_params(base, min_ground_range=150.0)
    assert {s.params.min_ground_range for s in cell.sensors} == {150.0}


def test_town_sets_the_buildings() -> None:
    grid = parse(_one_axis("town", "[0, 20, 40]", "0", preset="urban"))
    urban = grid.study.scenario
    assert urban.buildings                                  # the preset's own town...
    assert _cell(grid, "base").buildings == ()              # ...replaced: 0 = none
    assert _cell(grid, "base") == dataclasses.replace(urban, buildings=())
    for half in (20, 40):
        cell = _cell(grid, f"town={half}")
        assert cell == dataclasses.replace(urban, buildings=town_buildings(half_size=half))
        widths = {b[2] - b[0] for b in cell.buildings}
        assert widths == {2.0 * half} and len(cell.buildings) == 9


def test_snr_ref_db_sets_swerling_detection_and_inf_is_ideal() -> None:
    grid = parse(_one_axis("snr_ref_db", "[inf, 10]", "inf", preset="radar"))
    radar = grid.study.scenario
    assert {s.params.detection for s in radar.sensors} == {"swerling1"}
    assert _cell(grid, "base") == _with_params(radar, detection="ideal")
    assert {s.params.snr_ref_db for s in _cell(grid, "base").sensors} == {15.0}
    assert _cell(grid, "snr_ref_db=10") == _with_params(radar, detection="swerling1",
                                                        snr_ref_db=10.0)


def test_clutter_rate_sets_every_sensors_false_alarms() -> None:
    grid = parse(_one_axis("clutter_rate", "[0, 2.5]", "0"))
    assert _cell(grid, "clutter_rate=2.5") == _with_params(grid.study.scenario,
                                                           clutter_rate=2.5)


def test_birth_rate_sets_the_scenarios_births_and_the_trackers_birth_model() -> None:
    text = (_one_axis("birth_rate", "[0.03, 0.06, 0.12]", "0.06", preset="search")
            + '[[methods]]\nname = "gnn"\nplanner = "random"\nsearch = "off"\n'
            + '[methods.tracker]\nkind = "gnn"\n')
    grid = parse(text)
    for cell in grid.cells:
        rate = cell.study.scenario.birth_rate
        assert rate in (0.03, 0.06, 0.12) and cell.slug in ("base", f"birth_rate={rate:g}")
        # Every method's multi-target tracker is told the rate its targets are born at.
        assert {m.settings.tracker.birth_rate for m in cell.study.methods} == {rate}
        assert dataclasses.replace(cell.study.scenario, birth_rate=0.06) == grid.study.scenario


def test_birth_rate_needs_a_scenario_whose_targets_are_born() -> None:
    with pytest.raises(ConfigError) as exc:
        parse(_one_axis("birth_rate", "[0.0, 0.1]", "0.0"))
    assert exc.value.field == "axes[0].values" and "births" in exc.value.message


DEC = """\
runs = 1
steps = 4
[[methods]]
name = "random"
planner = "random"
[[methods]]
name = "pg"
planner = "pg"
[[methods]]
name = "jsfp"
planner = "dec-jsfp"
[[methods]]
name = "independent"
planner = "dec-independent"
[[methods]]
name = "sequential"
planner = "dec-sequential"
"""


@pytest.mark.parametrize("key,value,takes", [
    ("planner_params.p_loss", 0.2, {"jsfp", "sequential"}),
    ("planner_params.rounds", 7, {"jsfp", "independent"}),
    ("planner_params.alpha", 0.5, {"pg", "jsfp", "independent"}),
])
def test_a_setting_axis_reaches_exactly_the_planners_that_take_it(key: str, value: Any,
                                                                   takes: set[str]) -> None:
    grid = parse(DEC + f'[[axes]]\nfeature = "setting"\nkey = "{key}"\nvalues = [{value}]\n'
                       f"base = {value}\n")
    name = key.split(".", 1)[1]
    (cell,) = grid.cells
    for before, after in zip(grid.study.methods, cell.study.methods):
        if before.name in takes:
            assert after.settings.planner_params[name] == value
            expected = dict(before.settings.planner_params, **{name: value})
            assert after.settings.planner_params == expected
        else:
            assert after.settings == before.settings
    left = sorted({m.name for m in grid.study.methods} - takes,
                  key=[m.name for m in grid.study.methods].index)
    note = f"{key} is left out for {', '.join(left)} (their planners do not take it)"
    assert cell.notes == (note,)
    assert cell.notes[0] in cell.study.description


def test_a_setting_axis_on_a_method_setting_applies_to_every_method() -> None:
    grid = parse(HEAD + '[[axes]]\nfeature = "setting"\nkey = "tracker.miss_update"\n'
                        'values = ["negative", "none"]\nbase = "negative"\n')
    assert [c.slug for c in grid.cells] == ["base", "tracker.miss_update=none"]
    assert {m.settings.tracker.miss_update for m in grid.cells[1].study.methods} == {"none"}
    assert grid.cells[1].notes == ()


# ------------------------------------------------------------------------ validation


BAD = [
    # (replace this, with this, field named)
    ('feature = "sensor_speed"', 'feature = "speed"', "axes[0].feature"),
    ("base = 1.0", "base = 2.0", "axes[0].base"),
    ("base = 1.0\n", "", "axes[0].base"),
    ("values = [0.5, 1.0]", "values = []", "axes[0].values"),
    ("values = [0.5, 1.0]", "values = [0, 1.0]", "axes[0].values"),
    ("values = [0.5, 1.0]", "values = [-1, 1.0]", "axes[0].values"),
    ("values = [0.5, 1.0]", 'values = ["fast", 1.0]', "axes[0].values"),
    ("values = [0.5, 1.0]", "values = [nan, 1.0]", "axes[0].values"),
    ("values = [0.5, 1.0]", "values = [inf, 1.0]", "axes[0].values"),
    ("values = [0.5, 1.0]", "values = [1, 1.0]", "axes[0].values"),
    ("values = [0.5, 1.0]", "values = [true, 1.0]", "axes[0].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "clutter_rate"\nvalues = [0, -1]', "axes[1].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "min_ground_range"\nvalues = [0, 450]', "axes[1].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "min_ground_range"\nvalues = [0, 200]', "axes[1].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "town"\nvalues = [0, 70]', "axes[1].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "town"\nvalues = [0, -5]', "axes[1].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "snr_ref_db"\nvalues = [0, -inf]', "axes[1].values"),
    ('feature = "clutter_rate"', 'feature = "sensor_speed"', "axes[1].feature"),
    ('feature = "clutter_rate"', 'feature = "clutter_rate"\nkey = "horizon"', "axes[1].key"),
    ('feature = "clutter_rate"', 'feature = "setting"', "axes[1].key"),
    ('feature = "clutter_rate"', 'feature = "setting"\nkey = "planner_params.p_loss"',
     "axes[1].key"),
    ('feature = "clutter_rate"', 'feature = "setting"\nkey = "horizn"', "axes[1].key"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "setting"\nkey = "planner_params.alpha"\nvalues = [0, 1]', "axes[1].values"),
    ('feature = "clutter_rate"\nvalues = [0, 1]',
     'feature = "setting"\nkey = "horizon"\nvalues = [0, 1]', "axes[1].values"),
    ('feature = "clutter_rate"', 'feature = "clutter_rate"\nkee = "x"', "axes[1].kee"),
    ('method = "myopic"', 'method = "greedy"', "comparisons[0].method"),
    ('reference = "myopic"', 'reference = "K=1"', "comparisons[1].reference"),
    ('reference = "random"', 'reference = "myopic"', "comparisons[0].reference"),
    ('description = "tiny grid"', 'design = "diagonal"', "design"),
    ('description = "tiny grid"', 'axis = 1', "axis"),
    ("horizon = 2", "horizon = 0", "methods[2].horizon"),
]


@pytest.mark.parametrize("old,new,field", BAD, ids=[f"{b[2]}:{b[1][-18:]}" for b in BAD])
def test_bad_grid_file_exits_2_with_one_line_naming_the_field(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, old: str, new: str,
        field: str) -> None:
    assert old in GOOD
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new, 1))
    assert_bad_input(run(capsys, "grid", path, "--out", tmp_path / "out"), field)
    assert not (tmp_path / "out").exists()


def test_axes_are_required_and_one_axis_per_feature(capsys: pytest.CaptureFixture[str],
                                                   tmp_path: Path) -> None:
    path = tmp_path / "g.toml"
    path.write_text(HEAD)
    assert_bad_input(run(capsys, "grid", path), "axes")
    path.write_text("axes = []\n" + HEAD)
    assert_bad_input(run(capsys, "grid", path), "axes")
    path.write_text(GOOD + AXES)
    line = assert_bad_input(run(capsys, "grid", path), "axes[2].feature")
    assert "already varied by axes[0]" in line


def test_without_comparisons_the_references_are_compared() -> None:
    grid = parse(HEAD + AXES)
    assert not grid.comparisons_given
    assert [(c.method, c.reference) for c in grid.comparisons] == [
        ("myopic", "random"), ("olf2", "myopic"), ("olf2", "random")]
    with pytest.raises(ConfigError) as info:
        parse(HEAD.split("[[methods]]")[0] + '[[methods]]\nname = "a"\n' + AXES)
    assert info.value.field == "comparisons"


# --------------------------------------------------------------------------- running


@pytest.fixture(scope="module")
def grid_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("grid") / "g"
    res = run_grid(parse(GOOD), out, workers=1)
    assert res.ran == res.total == 3 * 3 * 2
    return out


def _frames(out: Path) -> dict[str, pd.DataFrame]:
    t = studies.load_study_dir(out)
    assert t.complete
    return {"steps": t.steps, "decisions": t.decisions.drop(columns="planning_seconds"),
            "sensors": t.sensors, "tracks": t.tracks, "gospa": t.gospa}


def assert_same_grid(a: Path, b: Path) -> None:
    cells = json.loads((a / "grid.json").read_text())["cells"]
    for cell in cells:
        fa, fb = _frames(a / cell["slug"]), _frames(b / cell["slug"])
        for name in studies.TABLES:
            pd.testing.assert_frame_equal(fa[name], fb[name], check_exact=True, obj=name)


def test_grid_directory_holds_grid_json_and_one_study_per_cell(grid_dir: Path) -> None:
    info = json.loads((grid_dir / "grid.json").read_text())
    assert [c["slug"] for c in info["cells"]] == ["base", "sensor_speed=0.5",
                                                  "clutter_rate=1"]
    assert info["cells"][1]["values"] == {"sensor_speed": "0.5", "clutter_rate": "0"}
    assert info["comparisons"][1] == {"method": "olf2", "reference": "myopic",
                                      "label": "K = 2 vs myopic"}
    assert info["file"]["runs"] == 2 and info["code"]["sensorplan"]
    grid = parse(GOOD)
    for cell in grid.cells:
        t = studies.load_study_dir(grid_dir / cell.slug)
        assert t.complete and t.study.resolved() == cell.study.resolved()
        # Common random numbers across cells: the same seed, so the same first truths.
        first = t.steps[(t.steps["step"] == 0) & (t.steps["method"] == "random")]
        if cell.slug == "base":
            base_first = first[["x", "y"]].to_numpy()
        np.testing.assert_array_equal(first[["x", "y"]].to_numpy(), base_first)


def test_rerun_skips_everything_and_a_changed_grid_is_refused(grid_dir: Path) -> None:
    parts = sorted(grid_dir.rglob("*.parquet"))
    before = {p: p.stat().st_mtime_ns for p in parts}
    res = run_grid(parse(GOOD), grid_dir, workers=2)
    assert res.ran == 0 and res.total == 18
    assert {p: p.stat().st_mtime_ns for p in parts} == before
    with pytest.raises(ConfigError) as info:
        run_grid(parse(GOOD.replace("values = [0, 1]", "values = [0, 2]")), grid_dir,
                 workers=1)
    assert info.value.field == "--out" and "different grid" in info.value.message
    assert "file.axes[1].values[1] (1 -> 2)" in info.value.message
    with pytest.raises(ConfigError, match="different grid.*runs"):
        run_grid(parse(GOOD.replace("runs = 2", "runs = 3")), grid_dir, workers=1)
    # The description and the comparisons do not change any run: allowed, and recorded.
    relabelled = GOOD.replace("tiny grid", "renamed").replace('label = "K = 2 vs myopic"',
                                                              'label = "lookahead"')
    assert run_grid(parse(relabelled), grid_dir, workers=1).ran == 0
    info_json = json.loads((grid_dir / "grid.json").read_text())
    assert info_json["comparisons"][1]["label"] == "lookahead"
    assert run_grid(parse(GOOD), grid_dir, workers=1).ran == 0
    assert {p: p.stat().st_mtime_ns for p in parts} == before


def test_a_cell_holding_another_study_is_refused_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "g"
    run_grid(parse(GOOD.replace("runs = 2", "runs = 1")), out, workers=1)
    shutil.rmtree(out / "clutter_rate=1")
    config = out / "base" / "config.resolved.json"
    data = json.loads(config.read_text())
    data["steps"] = 7
    config.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"base holds results of a different study"):
        run_grid(parse(GOOD.replace("runs = 2", "runs = 1")), out, workers=1)
    assert not (out / "clutter_rate=1").exists()
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "x").write_text("x")
    with pytest.raises(ConfigError, match="not a grid directory"):
        run_grid(parse(GOOD), tmp_path / "other", workers=1)


def test_interrupted_grid_keeps_what_finished_and_resumes(grid_dir: Path,
                                                          tmp_path: Path) -> None:
    out = tmp_path / "g"
    seen: list[int] = []

    def progress(done: int, total: int, already: int) -> None:
        seen.append(done)
        if done == 8:                                   # inside the second cell
            raise KeyboardInterrupt
    with pytest.raises(GridInterrupted) as info:
        run_grid(parse(GOOD), out, workers=1, progress=progress)
    assert (info.value.done, info.value.total, info.value.cell) == (8, 18, "sensor_speed=0.5")
    assert seen == list(range(9))
    assert len(list(out.rglob("m*.steps.parquet"))) == 8
    calls: list[tuple[int, int, int]] = []
    res = run_grid(parse(GOOD), out, workers=1, progress=lambda *a: calls.append(a))
    assert res.ran == 10 and calls[0] == (0, 10, 8) and calls[-1] == (10, 10, 8)
    assert_same_grid(grid_dir, out)


def test_same_results_on_dask_with_two_workers(grid_dir: Path, tmp_path: Path) -> None:
    run_grid(parse(GOOD), tmp_path / "dask", workers=2, scheduler="local", processes=False)
    assert_same_grid(grid_dir, tmp_path / "dask")
    meta = json.loads((tmp_path / "dask" / "base" / "meta.json").read_text())
    assert meta["sessions"][-1]["executor"].startswith("dask local")


@pytest.mark.slow
def test_same_results_with_one_and_two_worker_processes(grid_dir: Path,
                                                        tmp_path: Path) -> None:
    run_grid(parse(GOOD), tmp_path / "pool", workers=2)
    meta = json.loads((tmp_path / "pool" / "base" / "meta.json").read_text())
    assert meta["sessions"][-1]["executor"] == "process pool (2 workers)"
    assert_same_grid(grid_dir, tmp_path / "pool")


def test_grid_command_runs_resumes_refuses_and_reports(capsys: pytest.CaptureFixture[str],
                                                       tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    import sensorplan.cli.console

    # Plain progress lines stay quiet during the first seconds; this grid is quicker.
    monkeypatch.setattr(sensorplan.cli.console, "FIRST_LINE_SECONDS", 0.0)
    path = tmp_path / "g.toml"
    path.write_text(GOOD.replace("runs = 2", "runs = 1"))
    out = tmp_path / "out"
    code, stdout, err = run(capsys, "grid", path, "--out", out, "--workers", "1")
    assert code == 0, err
    assert "ran 9 of 9 (run, method) pairs in 3 cells" in stdout
    assert f"next: sensorplan report {out}" in stdout
    assert "9/9 done" in err and "ETA" in err          # one progress line across cells
    code, stdout, _ = run(capsys, "grid", path, "--out", out)
    assert code == 0 and "grid already complete" in stdout
    path.write_text(GOOD.replace("runs = 2", "runs = 1").replace("steps = 6", "steps = 7"))
    line = assert_bad_input(run(capsys, "grid", path, "--out", out), "--out")
    assert "different grid" in line and "file.steps (6 -> 7)" in line
    code, stdout, err = run(capsys, "report", out)
    assert code == 0, err
    assert f"report: {out / 'report' / 'report.html'}" in stdout
    for name in ("report.html", "summary.md", "heatmap_1.png", "heatmap_2.png",
                 "grid_statistics.csv"):
        assert (out / "report" / name).exists()


def test_grid_command_interrupted_says_what_is_saved(capsys: pytest.CaptureFixture[str],
                                                     tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorplan.study import grid_run

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        raise GridInterrupted(5, 18, "clutter_rate=1")
    monkeypatch.setattr(grid_run, "run_grid", interrupted)
    path = tmp_path / "g.toml"
    path.write_text(GOOD)
    code, stdout, err = run(capsys, "grid", path, "--out", tmp_path / "o")
    assert code == 130 and stdout == ""
    assert err == (f"interrupted in cell clutter_rate=1: 5 of 18 (run, method) pairs are "
                   f"saved in {tmp_path / 'o'}; run the same command again to resume\n")


def test_grid_command_stopped_by_a_real_ctrl_c_prints_one_line(
        capsys: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    # Through the signal handler, as from a terminal: the command's own line said what is
    # saved, and the entry point then added "error: interrupted" (two lines).
    import signal

    from sensorplan.study import grid_run

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            raise GridInterrupted(0, 18, "base") from None
        raise AssertionError("the Ctrl-C did not interrupt")
    monkeypatch.setattr(grid_run, "run_grid", interrupted)
    path = tmp_path / "g.toml"
    path.write_text(GOOD)
    code, stdout, err = run(capsys, "grid", path, "--out", tmp_path / "o")
    assert code == 130 and stdout == ""
    assert err.splitlines() == [f"interrupted in cell base: 0 of 18 (run, method) pairs are "
                                f"saved in {tmp_path / 'o'}; run the same command again to "
                                "resume"]


def test_bad_options(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "g.toml"
    path.write_text(GOOD)
    assert_bad_input(run(capsys, "grid", path, "-j", "0", "--out", tmp_path / "o"),
                     "--workers")
    assert_bad_input(run(capsys, "grid", path, "--scheduler", "nowhere", "--out",
                         tmp_path / "o"), "--scheduler")
    assert_bad_input(run(capsys, "grid", tmp_path / "missing.toml"),
                     str(tmp_path / "missing.toml"))


def test_help_describes_grids(capsys: pytest.CaptureFixture[str]) -> None:
    code, stdout, _ = run(capsys, "grid", "--help")
    assert code == 0
    for word in ("star", "full", "sensor_speed", "grid.json", "resume", "--scheduler"):
        assert word in stdout
    assert "SPEC" not in stdout and "issue" not in stdout.lower()


# ---------------------------------------------------------------------------- report


def _independent(cell_dir: Path, method: str, ref: str) -> tuple[int, float, float, float]:
    """Paired mean RMSE difference over all targets, with scipy's t-interval, straight
    from the cell's steps.parquet."""
    st = pd.read_parquet(cell_dir / "steps.parquet")
    st = st[st["step"] >= 1]
    rmse = st.groupby(["method", "run"])["error"].apply(lambda e: np.sqrt(np.mean(e ** 2)))
    d = (rmse[method] - rmse[ref]).to_numpy()
    lo, hi = stats.t.interval(0.95, d.size - 1, loc=d.mean(), scale=stats.sem(d))
    return d.size, float(d.mean()), float(lo), float(hi)


def test_heat_map_numbers_match_a_second_computation(grid_dir: Path, tmp_path: Path) -> None:
    written = write_report(grid_dir, tmp_path / "report")
    assert written.complete and written.runs == 6
    info, table = grid_statistics(grid_dir)
    panels = heatmap_panels(info)
    assert [p.cols for p in panels] == [("0.5", "1"), ("0", "1")]
    assert [p.base_cols for p in panels] == [(1,), (0,)]
    csv = pd.read_csv(tmp_path / "report" / "grid_statistics.csv")
    checked = 0
    for k, comp in enumerate(info["comparisons"]):
        rows = table[table["comparison"] == k]
        for p in panels:
            v = heatmap_values(p, rows)
            for c, slug in enumerate(p.slugs[0]):
                n, mean, lo, hi = _independent(grid_dir / slug, comp["method"],
                                               comp["reference"])
                np.testing.assert_allclose([v["mean"][0, c], v["lo"][0, c], v["hi"][0, c]],
                                           [mean, lo, hi], rtol=1e-10, atol=1e-10)
                assert v["n"][0, c] == n and v["run"][0, c]
                row = csv[(csv["comparison"] == k) & (csv["cell"] == slug)].iloc[0]
                np.testing.assert_allclose([row["mean"], row["mean_lo"], row["mean_hi"]],
                                           [mean, lo, hi], rtol=1e-10)
                verdict = "better" if hi < 0 else "worse" if lo > 0 else "inconclusive"
                assert row["verdict"] == verdict
                checked += 1
    assert checked == 2 * 4                             # the base cell is in both rows
    md = (tmp_path / "report" / "summary.md").read_text()
    assert "## K = 2 vs myopic" in md and "![Paired mean RMSE difference" in md


def test_method_statistics_match_a_second_computation(grid_dir: Path, tmp_path: Path) -> None:
    """Each method's mean RMSE and lost share with scipy's t-interval, the ANEES and the
    diverged runs, straight from each cell's steps.parquet; and the report draws them."""
    from sensorplan.study.grid_run import method_statistics

    written = write_report(grid_dir, tmp_path / "report")
    assert "methods" in written.figures                      # a star design: the lines
    got = method_statistics(grid_dir)
    info = json.loads((grid_dir / "grid.json").read_text())
    assert len(got) == len(info["cells"]) * len(info["methods"])
    for row in got.itertuples():
        st = pd.read_parquet(grid_dir / row.cell / "steps.parquet")
        st = st[(st["step"] >= 1) & (st["method"] == row.method)]
        per_run = st.groupby("run")
        rmse = per_run["error"].apply(lambda e: np.sqrt(np.mean(e ** 2))).to_numpy()
        lost = per_run["error"].apply(lambda e: np.mean(e > 50.0)).to_numpy()
        for x, (m, lo, hi) in ((rmse, (row.rmse, row.rmse_lo, row.rmse_hi)),
                               (lost, (row.lost, row.lost_lo, row.lost_hi))):
            if np.ptp(x) == 0:                                # no spread: a point interval
                ref = [x.mean()] * 3
            else:
                ref = [x.mean(), *stats.t.interval(0.95, x.size - 1, loc=x.mean(),
                                                   scale=stats.sem(x))]
            # Intervals stay where the metric lies: RMSE >= 0, a share in [0, 1].
            ref = np.clip(ref, 0.0, 1.0 if x is lost else None)
            np.testing.assert_allclose([m, lo, hi], ref, rtol=1e-10, atol=1e-12)
        assert row.anees == pytest.approx(st["nees"].mean(), rel=1e-12)
        assert row.diverged == int((per_run["error"].max() > 300.0).sum())
    md = (tmp_path / "report" / "summary.md").read_text()
    assert "## Methods across the cells" in md and "(methods.png)" in md


def _grey_pixels(png: Path) -> int:
    from matplotlib.image import imread

    img = imread(png)[..., :3]
    grey = np.array([int(NOT_RUN[i:i + 2], 16) / 255 for i in (1, 3, 5)])
    return int(np.all(np.abs(img - grey) < 1.5 / 255, axis=-1).sum())


def test_a_cell_not_run_is_grey(grid_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "g"
    shutil.copytree(grid_dir, out)
    full = write_report(out, tmp_path / "full")
    assert _grey_pixels(full.figures["heatmap_1"]) < 200     # anti-aliased edges only
    shutil.rmtree(out / "clutter_rate=1")
    written = write_report(out, tmp_path / "partial")
    assert not written.complete and written.runs == 4
    info, table = grid_statistics(out)
    row = table[(table["cell"] == "clutter_rate=1") & (table["comparison"] == 0)].iloc[0]
    assert row["status"] == "not run" and row["verdict"] == "not run"
    assert math.isnan(row["mean"])
    v = heatmap_values(heatmap_panels(info)[1], table[table["comparison"] == 0])
    assert list(v["run"][0]) == [True, False] and math.isnan(v["mean"][0, 1])
    # A grey cell of about an inch at 110 dpi: thousands of pixels.
    assert _grey_pixels(written.figures["heatmap_1"]) > 2000
    md = (tmp_path / "partial" / "summary.md").read_text()
    assert "| clutter_rate=1 | 0 |" in md and "(1 not run)" in md
    assert "not run" in (tmp_path / "partial" / "report.html").read_text()


def test_full_design_draws_a_two_dimensional_map(tmp_path: Path) -> None:
    text = (GOOD.replace("runs = 2", "runs = 1").replace("steps = 6", "steps = 4")
            .replace('description = "tiny grid"', 'design = "full"'))
    grid = parse(text)
    info = json.loads(json.dumps(studies_grid_resolved(grid)))
    (panel,) = heatmap_panels(info)
    assert (panel.rows, panel.cols) == (("0.5", "1"), ("0", "1"))
    assert panel.slugs == (("sensor_speed=0.5,clutter_rate=0", "sensor_speed=0.5,clutter_rate=1"),
                           ("sensor_speed=1,clutter_rate=0", "sensor_speed=1,clutter_rate=1"))
    assert (panel.base_rows, panel.base_cols) == ((1,), (0,))
    three = parse(text + '[[axes]]\nfeature = "town"\nvalues = [0, 20]\n')
    panels = heatmap_panels(json.loads(json.dumps(studies_grid_resolved(three))))
    assert [p.title for p in panels] == ["town = 0", "town = 20"]
    assert panels[1].slugs[0][0] == "sensor_speed=0.5,clutter_rate=0,town=20"


def studies_grid_resolved(grid: Any) -> dict[str, Any]:
    from sensorplan.study.grid_run import grid_resolved

    return grid_resolved(grid)


# ------------------------------------------------------------------ the shipped grid


def test_lookahead_map_is_the_chosen_grid() -> None:
    grid = load_grid(ROOT / "studies" / "lookahead_map.toml")
    s = grid.study
    assert s.description == ("Where lookahead pays: OLF K = 3 vs myopic over sensor speed, "
                             "blind disc, buildings and detection (100 paired runs per cell)")
    assert (s.runs, s.steps, s.seed, s.scenario_source) == (100, 100, 2718, "preset paper")
    assert grid.design == "star"
    assert [(a.feature, a.values, a.base) for a in grid.axes] == [
        ("sensor_speed", (0.125, 0.25, 0.5, 1.0), 1.0),
        ("min_ground_range", (150, 250, 350), 250),
        ("town", (0, 20, 30, 40), 0),
        ("snr_ref_db", (math.inf, 20, 15, 10), math.inf)]
    assert {(m.name, m.settings.planner, m.settings.horizon, m.settings.steps_per_epoch,
             m.settings.objective, m.settings.execution, m.settings.visibility)
            for m in s.methods} == {
        ("myopic e1", "pg", 1, 1, "terminal", "olf", "probabilistic"),
        ("olf3 terminal e1", "pg", 3, 1, "terminal", "olf", "probabilistic"),
        ("olf3 cumulative e1", "pg", 3, 1, "cumulative", "olf", "probabilistic"),
        ("myopic terminal e2", "pg", 1, 2, "terminal", "olf", "probabilistic"),
        ("myopic cumulative e2", "pg", 1, 2, "cumulative", "olf", "probabilistic"),
        ("olf3 terminal e2", "pg", 3, 2, "terminal", "olf", "probabilistic"),
        ("olf3 cumulative e2", "pg", 3, 2, "cumulative", "olf", "probabilistic")}
    assert len(s.methods) == 7
    assert [(c.method, c.reference) for c in grid.comparisons] == [
        ("olf3 terminal e1", "myopic e1"), ("olf3 cumulative e1", "myopic e1"),
        ("olf3 terminal e2", "myopic terminal e2"),
        ("olf3 cumulative e2", "myopic cumulative e2")]
    assert len(grid.cells) == 1 + 3 + 2 + 3 + 3
    assert sum(len(c.study.tasks()) for c in grid.cells) == 8400
