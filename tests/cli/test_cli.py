"""The command line: `plan`, `simulate`, exit codes and the one-line errors."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sensorplan.cli.app import main
from sensorplan.config.files import dumps_result, result_to_dict
from sensorplan.planners import PLANNERS, PlanResult
from sensorplan.planners.problem import Plan, move_vectors

from cli_helpers import SPEC7, SPEC7_TEXT, assert_bad_input, run
from cli_helpers import set_path as _set

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "configs" / "quick.toml"

BASE_KEYS = {"planner", "plan", "potential", "information", "seconds"}
ACTION_KEYS = {"epoch", "position", "heading", "target", "measurements"}


def write_json(tmp_path: Path, data: Any, name: str = "problem.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


# --------------------------------------------------------------------------- plan


def test_plan_spec7_example_with_random(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                        ) -> None:
    path = tmp_path / "p.json"
    path.write_text(SPEC7_TEXT)
    code, out, err = run(capsys, "plan", path, "--planner", "random")
    assert (code, err) == (0, "")
    res = json.loads(out)
    assert set(res) == BASE_KEYS                        # no converged/sweeps for random
    assert res["planner"] == "random"
    assert len(res["plan"]) == 1 and len(res["plan"][0]) == 3
    moves = move_vectors((20.0, 40.0))
    prev = np.array([100.0, 100.0])
    for k, action in enumerate(res["plan"][0], start=1):
        assert set(action) == ACTION_KEYS
        assert action["epoch"] == k
        assert action["target"] == 0
        assert isinstance(action["measurements"], int) and 0 <= action["measurements"] <= 1
        pos = np.array(action["position"])
        assert np.min(np.abs(pos - prev - moves).max(axis=1)) < 1e-6   # one move per epoch
        assert -math.pi < action["heading"] <= math.pi
        prev = pos
    assert res["potential"] >= 0
    assert res["potential"] == pytest.approx(sum(res["information"]), rel=1e-9)
    assert len(res["information"]) == 1
    assert res["seconds"] >= 0


def test_plan_is_deterministic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_json(tmp_path, {**SPEC7, "planner": {"name": "random", "seed": 5}})
    first = json.loads(run(capsys, "plan", path)[1])
    second = json.loads(run(capsys, "plan", path)[1])
    first.pop("seconds"), second.pop("seconds")
    assert first == second


def test_planner_option_overrides_the_file(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    path = write_json(tmp_path, {**SPEC7, "planner": {"name": "random", "seed": 0}})
    other = "pg" if "pg" in PLANNERS else "random"
    code, out, _ = run(capsys, "plan", path, "--planner", other)
    assert code == 0
    res = json.loads(out)
    assert res["planner"] == other
    if other == "pg":
        assert set(res) == BASE_KEYS | {"converged", "sweeps"}
        assert isinstance(res["converged"], bool) and isinstance(res["sweeps"], int)


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_every_registered_planner_gives_the_spec_keys(
        name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_json(tmp_path, {**SPEC7, "horizon": 2, "planner": {"name": name}})
    code, out, err = run(capsys, "plan", path)
    assert code == 0, err
    res = json.loads(out)
    extra = {"converged", "sweeps"} if name in ("pg", "pg-refine") else set()
    assert set(res) == BASE_KEYS | extra
    assert res["planner"] == name


def test_result_to_dict_layout() -> None:
    plan = Plan(np.array([[[120.0, 100.0], [140.0, 120.0]]]), np.array([[0, 1]]))
    result = PlanResult("pg", plan, 3.25, np.array([1.0, 2.25]), np.array([[0.5, -0.25]]),
                        np.array([[1, 0]]), converged=True, sweeps=2, seconds=0.004)
    expected = {
        "planner": "pg",
        "plan": [[{"epoch": 1, "position": [120.0, 100.0], "heading": 0.5, "target": 0,
                   "measurements": 1},
                  {"epoch": 2, "position": [140.0, 120.0], "heading": -0.25, "target": 1,
                   "measurements": 0}]],
        "potential": 3.25, "information": [1.0, 2.25], "converged": True, "sweeps": 2,
        "seconds": 0.004}
    assert result_to_dict(result) == expected
    assert list(result_to_dict(result)) == list(expected)       # documented key order
    assert json.loads(dumps_result(result)) == expected
    random_result = PlanResult("random", plan, 3.25, np.array([1.0, 2.25]),
                               np.array([[0.5, -0.25]]), np.array([[1, 0]]))
    assert set(result_to_dict(random_result)) == BASE_KEYS




def _delete(key: str) -> Callable[[dict[str, Any]], None]:
    return lambda d: d.pop(key)


ASYM = [[400, 1, 0, 0], [0, 400, 0, 0], [0, 0, 4, 0], [0, 0, 0, 4]]
NOT_PD = [[400, 0, 0, 0], [0, -400, 0, 0], [0, 0, 4, 0], [0, 0, 0, 4]]

#: (id, mutation of the documented example, field named in the error)
BAD_JSON = [
    ("unknown key", _set("foo", 1), "foo"),
    ("unknown nested key", _set("sensors.0.altitud", 500), "sensors[0].altitud"),
    ("unknown planner key", _set("planner.gamma", 0.1), "planner.gamma"),
    ("missing horizon", _delete("horizon"), "horizon"),
    ("missing targets", _delete("targets"), "targets"),
    ("missing sensor heading", lambda d: d["sensors"][0].pop("heading"), "sensors[0].heading"),
    ("float for int", _set("horizon", 2.0), "horizon"),
    ("bool for int", _set("steps_per_epoch", True), "steps_per_epoch"),
    ("string for float", _set("dt", "1.0"), "dt"),
    ("bool for float", _set("sensors.0.altitude", False), "sensors[0].altitude"),
    ("null for float", _set("process_noise", None), "process_noise"),
    ("object for list", _set("targets", {"mean": [1, 2, 3, 4]}), "targets"),
    ("short mean", _set("targets.0.mean", [1, 2, 3]), "targets[0].mean"),
    ("cov rows", _set("targets.0.cov", [[1, 0, 0, 0]] * 3), "targets[0].cov"),
    ("cov row length", _set("targets.0.cov.1", [0, 1, 0]), "targets[0].cov[1]"),
    ("position length", _set("sensors.0.position", [1, 2, 3]), "sensors[0].position"),
    ("map not object", _set("map", 600), "map"),
    ("nan mean", _set("targets.0.mean.0", float("nan")), "targets[0].mean[0]"),
    ("inf cov", _set("targets.0.cov.0.0", float("inf")), "targets[0].cov[0][0]"),
    ("inf heading", _set("sensors.0.heading", float("-inf")), "sensors[0].heading"),
    ("cov not symmetric", _set("targets.0.cov", ASYM), "targets[0].cov"),
    ("cov not PD", _set("targets.0.cov", NOT_PD), "targets[0].cov"),
    ("sensor outside map", _set("sensors.0.position", [100, 601]), "sensors[0].position"),
    ("sensor below map", _set("sensors.0.position", [-1, 100]), "sensors[0].position"),
    ("dt zero", _set("dt", 0), "dt"),
    ("dt negative", _set("dt", -1.0), "dt"),
    ("steps_per_epoch zero", _set("steps_per_epoch", 0), "steps_per_epoch"),
    ("horizon zero", _set("horizon", 0), "horizon"),
    ("move zero", _set("sensors.0.moves", [20, 0]), "sensors[0].moves"),
    ("move negative", _set("sensors.0.moves", [-20]), "sensors[0].moves"),
    ("no moves", _set("sensors.0.moves", []), "sensors[0].moves"),
    ("altitude zero", _set("sensors.0.altitude", 0), "sensors[0].altitude"),
    ("min range", _set("sensors.0.min_ground_range", -1), "sensors[0].min_ground_range"),
    ("max range", _set("sensors.0.max_ground_range", 0), "sensors[0].max_ground_range"),
    ("range ref", _set("sensors.0.range_ref", 0), "sensors[0].range_ref"),
    ("resolution", _set("sensors.0.range_resolution", -30), "sensors[0].range_resolution"),
    ("beamwidth", _set("sensors.0.beamwidth", 0), "sensors[0].beamwidth"),
    ("slope", _set("sensors.0.monopulse_slope", 0), "sensors[0].monopulse_slope"),
    ("fov", _set("sensors.0.fov_half_angle", 0), "sensors[0].fov_half_angle"),
    ("min > max range", _set("sensors.0.min_ground_range", 460), "sensors[0].min_ground_range"),
    ("unknown planner", _set("planner.name", "simulated-annealing"), "planner.name"),
    ("unknown visibility", _set("visibility", "optimistic"), "visibility"),
    ("unknown objective", _set("objective", "average"), "objective"),
    ("max_plans for pg", _set("planner.max_plans", 10), "planner.max_plans"),
    ("no targets", _set("targets", []), "targets"),
    ("no sensors", _set("sensors", []), "sensors"),
]


@pytest.mark.parametrize("mutate,field", [c[1:] for c in BAD_JSON],
                         ids=[c[0] for c in BAD_JSON])
def test_plan_bad_input(mutate: Callable[[dict[str, Any]], None], field: str, tmp_path: Path,
                        capsys: pytest.CaptureFixture[str]) -> None:
    data = copy.deepcopy(SPEC7)
    if not field.startswith("planner."):
        data["planner"] = {"name": "random", "seed": 0}      # fast: only the input is wrong
    mutate(data)
    assert_bad_input(run(capsys, "plan", write_json(tmp_path, data)), field)


#: An out-of-range value of every setting of every built-in planner: (planner, key, value).
BAD_PLANNER_SETTINGS = [
    ("pg", "alpha", 0), ("pg", "alpha", 1.0), ("pg", "beta", 1.5), ("pg", "beta", -0.1),
    ("pg", "max_inner", 0), ("pg", "max_outer", -3), ("pg", "seed", -1),
    ("pg", "time_budget", 0.0), ("pg-refine", "alpha", 1.2), ("pg-refine", "time_budget", -2),
    ("sequential-greedy", "time_budget", -1e-3), ("sequential-greedy", "seed", -5),
    ("brute-force", "max_plans", 0), ("brute-force", "chunk", -1), ("brute-force", "seed", -1),
    ("random", "seed", -7),
    ("raster", "sweep", "spiral"), ("raster", "revisit_every", -1), ("raster", "seed", -2),
    ("dec-jsfp", "rounds", 0), ("dec-jsfp", "p_loss", 1.5), ("dec-jsfp", "delay", -1),
    ("dec-jsfp", "comm_range", 0.0), ("dec-jsfp", "mode", "gossip"),
    ("dec-jsfp", "transport", "pigeon"), ("dec-jsfp", "timeout", -1.0),
    ("dec-jsfp", "max_inner", 0), ("dec-jsfp", "seed", -1),
    ("dec-independent", "rounds", -2), ("dec-independent", "beta", 1.0),
    ("dec-sequential", "p_loss", -0.5), ("dec-sequential", "comm_range", -10.0),
    ("dec-sequential", "timeout", 0),
]


@pytest.mark.parametrize("name,key,value", BAD_PLANNER_SETTINGS,
                         ids=[f"{n} {k}={v}" for n, k, v in BAD_PLANNER_SETTINGS])
def test_plan_refuses_an_out_of_range_planner_setting(name: str, key: str, value: Any,
                                                      tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    data = {**SPEC7, "planner": {"name": name, key: value}}
    line = assert_bad_input(run(capsys, "plan", write_json(tmp_path, data)), f"planner.{key}")
    assert "must be" in line or "unknown" in line


def test_every_planner_setting_has_an_out_of_range_case() -> None:
    """Each setting any built-in planner declares (sensorplan.limits.param) is refused
    through the command line by a case above."""
    from sensorplan.limits import declared_params
    from sensorplan.planners.registry import BUILTIN

    declared = {f.name for name in BUILTIN for f, _ in declared_params(PLANNERS[name])}
    assert declared == {key for _, key, _ in BAD_PLANNER_SETTINGS}


def test_plan_brute_force_above_max_plans(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    data = {**SPEC7, "planner": {"name": "brute-force", "max_plans": 5}}
    assert_bad_input(run(capsys, "plan", write_json(tmp_path, data)), "planner.max_plans")


def test_plan_bad_files_and_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "missing.json"
    assert_bad_input(run(capsys, "plan", missing), str(missing))
    broken = tmp_path / "broken.json"
    broken.write_text('{"horizon": 3,')
    assert_bad_input(run(capsys, "plan", broken), str(broken))
    top = write_json(tmp_path, [SPEC7], "list.json")
    assert "JSON object" in assert_bad_input(run(capsys, "plan", top), str(top))
    dup = tmp_path / "dup.json"
    dup.write_text('{"horizon": 3, "horizon": 4}')
    assert_bad_input(run(capsys, "plan", dup), "horizon")
    assert_bad_input(run(capsys, "plan", tmp_path), str(tmp_path))          # a directory
    good = write_json(tmp_path, SPEC7)
    assert_bad_input(run(capsys, "plan", good, "--planner", "nope"), "--planner")
    assert_bad_input(run(capsys, "plan", good, "--planner"), "--planner")
    assert_bad_input(run(capsys, "plan", good, "--bogus"), "--bogus")
    assert_bad_input(run(capsys, "plan"), "PROBLEM.json")
    assert_bad_input(run(capsys, "frobnicate"), "usage")


def test_help_is_useful(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--help")
    assert code == 0 and "plan" in out and "simulate" in out
    code, out, _ = run(capsys, "plan", "--help")
    assert code == 0
    for word in ("PROBLEM.json", "--planner", "converged", "stderr"):
        assert word in out
    code, out, _ = run(capsys, "simulate", "--help")
    assert code == 0
    for word in ("--preset", "--planner", "--horizon", "--steps-per-epoch", "--execution",
                 "--steps", "--seed", "--visibility", "--objective", "--miss-update", "--out",
                 "RMSE"):
        assert word in out, word
    code, out, _ = run(capsys)                         # no arguments: the help
    assert code == 0 and "simulate" in out


def test_unexpected_errors_are_one_line_with_status_1(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sensorplan.config

    def broken(*args: Any, **kwargs: Any) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(sensorplan.config, "load_decision", broken)
    code, out, err = run(capsys, "plan", write_json(tmp_path, SPEC7))
    assert (code, out) == (1, "")
    assert err.splitlines() == [
        "error: internal error: RuntimeError: boom (set SENSORPLAN_DEBUG=1 for the traceback)"]
    monkeypatch.setenv("SENSORPLAN_DEBUG", "1")
    with pytest.raises(RuntimeError, match="boom"):
        main(["plan", str(tmp_path / "problem.json")])


def test_console_script_in_a_subprocess(tmp_path: Path) -> None:
    script = Path(sys.executable).parent / "sensorplan"
    if not script.exists():
        pytest.skip(f"console script not installed next to {sys.executable}")
    bad = write_json(tmp_path, {**SPEC7, "dt": -1.0}, "bad.json")
    proc = subprocess.run([str(script), "plan", str(bad)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr.splitlines() == ["error: dt: must be in [0.001, 3600] s, got -1.0"]
    good = write_json(tmp_path, SPEC7, "good.json")
    proc = subprocess.run([sys.executable, "-m", "sensorplan", "plan", str(good), "--planner",
                           "random"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert set(json.loads(proc.stdout)) == BASE_KEYS


# ----------------------------------------------------------------------- simulate


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else
                                            "-inf" if v == -math.inf else repr(v))
    if isinstance(v, (int, str)):
        return json.dumps(v)
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


def to_toml(d: dict[str, Any], prefix: str = "") -> str:
    """Tiny TOML writer for the tests (scalars, lists, tables, arrays of tables)."""
    lines, tables, arrays = [], [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            arrays.append((k, v))
        else:
            lines.append(f"{k} = {_toml_value(v)}")
    for k, v in tables:
        lines += [f"[{prefix}{k}]", to_toml(v, f"{prefix}{k}.")]
    for k, items in arrays:
        for item in items:
            lines += [f"[[{prefix}{k}]]", to_toml(item, f"{prefix}{k}.")]
    return "\n".join(lines)


BASE_TOML: dict[str, Any] = {
    "dt": 1.0,
    "map": {"width": 600.0, "height": 600.0},
    "initial": {"cov": [[400.0, 0, 0, 0], [0, 400.0, 0, 0], [0, 0, 4.0, 0], [0, 0, 0, 4.0]]},
    "tracker": {"miss_update": "negative"},
    "planning": {"planner": "random", "horizon": 1, "planner_params": {}},
    "run": {"steps": 3, "seed": 0},
    "targets": [{"kind": "cv", "position": [300.0, 200.0]}],
    "sensors": [{"altitude": 500.0, "position": [100.0, 100.0], "heading": 0.0}],
}

#: (id, mutation of BASE_TOML, field named in the error)
BAD_TOML = [
    ("unknown key", _set("foo", 1), "foo"),
    ("unknown table key", _set("map.depth", 1.0), "map.depth"),
    ("unknown sensor key", _set("sensors.0.altitud", 1.0), "sensors[0].altitud"),
    ("planner seed", _set("planning.planner_params.seed", 1), "planning.planner_params.seed"),
    ("missing targets", _delete("targets"), "targets"),
    ("missing sensors", _delete("sensors"), "sensors"),
    ("string for float", _set("dt", "fast"), "dt"),
    ("float for int", _set("planning.horizon", 1.5), "planning.horizon"),
    ("bool for int", _set("run.steps", True), "run.steps"),
    ("table for list", _set("targets", {"kind": "cv"}), "targets"),
    ("cov rows", _set("initial.cov", [[1.0, 0, 0, 0]] * 3), "initial.cov"),
    ("box length", _set("initial.target_box", [1.0]), "initial.target_box"),
    ("position length", _set("sensors.0.position", [1.0, 2.0, 3.0]), "sensors[0].position"),
    ("nan", _set("process_noise", float("nan")), "process_noise"),
    ("inf", _set("sensors.0.altitude", float("inf")), "sensors[0].altitude"),
    ("cov not symmetric", _set("initial.cov", ASYM), "initial.cov"),
    ("cov not PD", _set("initial.cov", NOT_PD), "initial.cov"),
    ("sensor outside map", _set("sensors.0.position", [700.0, 100.0]), "sensors[0].position"),
    ("target outside map", _set("targets.0.position", [300.0, -5.0]), "targets[0].position"),
    ("dt zero", _set("dt", 0.0), "dt"),
    ("steps_per_epoch zero", _set("planning.steps_per_epoch", 0), "planning.steps_per_epoch"),
    ("horizon zero", _set("planning.horizon", 0), "planning.horizon"),
    ("steps zero", _set("run.steps", 0), "run.steps"),
    ("seed negative", _set("run.seed", -1), "run.seed"),
    ("move zero", _set("sensors.0.moves", [0.0]), "sensors[0].moves"),
    ("altitude", _set("sensors.0.altitude", -500.0), "sensors[0].altitude"),
    ("range ref", _set("sensors.0.range_ref", 0.0), "sensors[0].range_ref"),
    ("resolution", _set("sensors.0.range_resolution", 0.0), "sensors[0].range_resolution"),
    ("beamwidth", _set("sensors.0.beamwidth", 0.0), "sensors[0].beamwidth"),
    ("slope", _set("sensors.0.monopulse_slope", 0.0), "sensors[0].monopulse_slope"),
    ("fov", _set("sensors.0.fov_half_angle", 0.0), "sensors[0].fov_half_angle"),
    ("min > max range", _set("sensors.0.max_ground_range", 200.0),
     "sensors[0].min_ground_range"),
    ("alpha", _set("planning", {"planner": "pg", "planner_params": {"alpha": 1.0}}),
     "planning.planner_params.alpha"),
    ("beta", _set("planning", {"planner": "pg", "planner_params": {"beta": 0.0}}),
     "planning.planner_params.beta"),
    ("alpha for random", _set("planning.planner_params", {"alpha": 0.3}),
     "planning.planner_params.alpha"),
    ("max_plans for random", _set("planning.planner_params.max_plans", 10),
     "planning.planner_params.max_plans"),
    ("unknown planner", _set("planning.planner", "nope"), "planning.planner"),
    ("unknown visibility", _set("planning.visibility", "x"), "planning.visibility"),
    ("unknown objective", _set("planning.objective", "x"), "planning.objective"),
    ("unknown execution", _set("planning.execution", "closed"), "planning.execution"),
    ("unknown miss update", _set("tracker.miss_update", "x"), "tracker.miss_update"),
    ("unknown tracker kind", _set("tracker.kind", "jpda"), "tracker.kind"),
    ("unknown kind", _set("targets.0.kind", "ballistic"), "targets[0].kind"),
    ("negative speed", _set("targets.0.speed", -1.0), "targets[0].speed"),
    ("speed range", _set("initial.speed_range", [5.0, 1.0]), "initial.speed_range"),
]


@pytest.mark.parametrize("mutate,field", [c[1:] for c in BAD_TOML],
                         ids=[c[0] for c in BAD_TOML])
def test_simulate_bad_scenario(mutate: Callable[[dict[str, Any]], None], field: str,
                               tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = copy.deepcopy(BASE_TOML)
    mutate(data)
    path = tmp_path / "scenario.toml"
    path.write_text(to_toml(data))
    out = tmp_path / "out"
    assert_bad_input(run(capsys, "simulate", path, "--out", out), field)
    assert not out.exists()


BAD_OPTIONS = [
    (["--horizon", "0"], "--horizon"), (["--horizon", "x"], "--horizon"),
    (["--steps-per-epoch", "0"], "--steps-per-epoch"), (["--steps", "0"], "--steps"),
    (["--seed", "-1"], "--seed"), (["--execution", "closed"], "--execution"),
    (["--planner", "nope"], "--planner"), (["--visibility", "x"], "--visibility"),
    (["--objective", "x"], "--objective"), (["--miss-update", "x"], "--miss-update"),
    (["--preset", "nope"], "--preset"), (["--frobnicate"], "--frobnicate"),
]


@pytest.mark.parametrize("args,field", BAD_OPTIONS, ids=[a[0] for a, _ in BAD_OPTIONS])
def test_simulate_bad_options(args: list[str], field: str, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert_bad_input(run(capsys, "simulate", *args, "--out", out), field)
    assert not out.exists()


def test_simulate_has_an_option_per_declared_setting_with_its_default() -> None:
    """The options come from the settings' declarations: names, placeholder, help text and
    the default of a RunSettings() (an independent source of the defaults)."""
    import typer

    from sensorplan.cli.app import app
    from sensorplan.simulation.settings import RunSettings, all_settings

    command = typer.main.get_command(app).commands["simulate"]   # type: ignore[attr-defined]
    options = {p.name: p for p in command.params}
    defaults = RunSettings()
    declared = [(path, f, s) for _, path, f, s in all_settings() if s.cli]
    assert {"planner", "horizon", "steps_per_epoch", "execution", "visibility", "objective",
            "steps", "miss_update"} <= {f.name for _, f, _ in declared}
    for path, f, s in declared:
        option = options[f.name]
        names = tuple(n for spec in s.cli for n in spec.split("/"))   # "--a/--no-a" flags
        assert tuple(option.opts + option.secondary_opts) == names
        assert option.default is None
        assert option.metavar == ("" if option.is_flag else s.metavar)
        value: Any = defaults
        for part in path.split("."):
            value = getattr(value, part)
        if option.is_flag:                      # the flag that is on: --gate or --no-gate
            value = option.opts[0] if value else option.secondary_opts[0]
        if f.default == "auto":                 # resolved by the settings (reward: by search)
            assert value in s.choices and value != "auto"
            value = "auto"
        assert option.help.startswith(s.brief.removesuffix("."))
        assert option.help.endswith(f"[default: {value}]"), option.help
        assert option.rich_help_panel == {"planning": "Planning", "tracker": "Tracking",
                                          "run": "Run"}[s.section]
    assert "brute-force" in options["planner"].help            # registered names listed
    assert set(options) == {f.name for _, f, _ in declared} | {"config", "preset", "seed",
                                                                "out", "animate",
                                                                "animation_format"}


def test_simulate_file_and_preset_conflict(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert_bad_input(run(capsys, "simulate", QUICK, "--preset", "paper", "--out", tmp_path),
                     "--preset")
    broken = tmp_path / "broken.toml"
    broken.write_text("dt = = 1\n")
    assert_bad_input(run(capsys, "simulate", broken, "--out", tmp_path), str(broken))
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert_bad_input(run(capsys, "simulate", QUICK, "--out", blocker), "--out")


def test_simulate_planner_refusing_mid_run(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    result = run(capsys, "simulate", QUICK, "--planner", "brute-force", "--horizon", "3",
                 "--out", tmp_path / "out")
    assert_bad_input(result, "planning.planner_params.max_plans")


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def test_simulate_writes_reproducible_outputs(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    runs = {}
    for name, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        code, out, err = run(capsys, "simulate", QUICK, "--steps", "8", "--seed", seed,
                             "--out", tmp_path / name)
        assert code == 0, err
        assert "RMSE" in out and "missed looks" in out and "decisions" in out
        assert (tmp_path / name / "episode.png").stat().st_size > 0
        runs[name] = _arrays(tmp_path / name / "episode.npz")
    a, b, c = runs["a"], runs["b"], runs["c"]
    assert set(a) == set(b)
    assert a["truth"].shape[0] == 9
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert not np.array_equal(a["truth"], c["truth"])
    # The data files are byte-identical; wall-clock timings live in their own sidecar.
    for name in ("episode.npz", "episode.png"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert (tmp_path / "a" / "episode.npz").read_bytes() != \
        (tmp_path / "c" / "episode.npz").read_bytes()
    assert (tmp_path / "a" / "episode.timing.json").exists()


def test_simulate_options_reach_the_run(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    from sensorplan.simulation import Episode

    code, _, err = run(capsys, "simulate", "--preset", "paper", "--steps", "4", "-K", "2",
                       "-e", "2", "--execution", "ol", "--visibility", "mean",
                       "--objective", "cumulative", "--miss-update", "none",
                       "--planner", "random", "--out", tmp_path)
    assert code == 0, err
    ep = Episode.load(tmp_path / "episode.npz")
    s = ep.settings
    assert (s.planner, s.horizon, s.steps_per_epoch, s.execution, s.steps, s.visibility,
            s.objective, s.tracker.miss_update) == ("random", 2, 2, "ol", 4, "mean",
                                                    "cumulative", "none")
    assert len(ep.target_kinds) == 5 and ep.sensor_positions.shape[1] == 3


def test_a_swarm_summary_lists_a_few_rows_and_the_totals(tmp_path, capsys):
    """30 targets and 25 sensors: the tables show the first 10 of each, say how many more
    there are, and the totals cover all of them."""
    from cli_helpers import run

    sc = tmp_path / "many.toml"
    sc.write_text('[map]\nwidth = 3000.0\nheight = 3000.0\n[initial]\n'
                  'target_box = [100.0, 2900.0]\nsensor_box = [50.0, 2950.0]\n'
                  + "[[targets]]\n" * 30 + "[[sensors]]\n" * 25)
    code, out, err = run(capsys, "simulate", sc, "--planner", "random", "--steps", "3",
                         "--out", tmp_path / "o")
    assert code == 0, err
    flat = " ".join(out.split())
    assert "targets 0-9 of 30 shown" in flat and "sensors 0-9 of 25 shown" in flat
    lines = [ln for ln in out.splitlines() if ln.startswith("│ all ") and "│" in ln[6:]]
    assert lines                                     # the group and sensor totals remain
    looks = int(out.split("Sensors")[1].split("│ all")[1].split("│")[2])
    assert looks == 3 * 25                           # random looks every step, every sensor
