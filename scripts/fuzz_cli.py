"""Mutation fuzzing of the real command line: one subprocess per case (docs/robustness.md).

Each case is rebuilt from its seed, kind and index alone (``SEED:KIND:i`` seeds the
hypothesis draws), so a failing case can be run again. The kinds:

- ``plan``: a decision JSON (the harness's documents of ``tests/fuzz_docs.py``, the newer
  keys included, under every built-in planner) mutated by ``fuzz_docs.mutate``, sometimes
  damaged as text; or a valid document at the edges of its ranges; sometimes ``--planner``.
- ``simulate``, ``agents``: a scenario file (or a preset) mutated the same way, plus
  options drawn from each command's own, with valid and invalid values, and now and then
  an output place that cannot be written, a Ctrl-C, or a standard output closed early.
- ``study``, ``grid``: a study or grid file (its scenario file too) mutated, plus
  ``--workers``, ``--scheduler`` and ``--out``.

Every outcome is checked against the contract (``fuzz_docs.check_outcome``), and against an
oracle of what the mutations must give: a case whose every change is bad by itself (an
unknown key, a value of the wrong type, out of its documented range, non-finite, a key
written twice, an invalid option value) must be refused (exit 2), and its error line must
name the changed field (or the file, or the option). Those two checks give *suspects*:
they are read by hand, because a value can also be refused by a joint rule that names
another field. Everything else the contract does not allow (a traceback, an exit status
other than 0, 2, 130 or 141, a hang, a process left behind, two error lines) is a
*defect*.

    python scripts/fuzz_cli.py --kind plan --seed 9101 --cases 2000 --out fuzz-out

writes ``fuzz-out/plan-9101/cases.jsonl.gz`` (every case: document, arguments, exit
status, seconds, verdict, first stderr line) and a directory per failing case (its files,
``case.json`` with the arguments, stdout and stderr), and prints a summary.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "src"))

from hypothesis import strategies as st  # noqa: E402
from hypothesis.control import BuildContext  # noqa: E402
from hypothesis.errors import StopTest  # noqa: E402
from hypothesis.internal.conjecture.data import ConjectureData  # noqa: E402

import fuzz_docs as fz  # noqa: E402
from sensorplan.limits import RANGES, Range  # noqa: E402

KINDS = ("plan", "simulate", "study", "grid", "agents")
BUILTIN_PLANNERS = ("pg", "pg-refine", "sequential-greedy", "brute-force", "random",
                    "dec-jsfp", "dec-independent", "dec-sequential")
DEC_PLANNERS = ("dec-jsfp", "dec-independent", "dec-sequential")
#: The settings each decentralized planner takes (sensorplan.decentral.planners).
DEC_SETTINGS = {
    "dec-jsfp": {"rounds", "mode", "p_loss", "delay", "comm_range", "transport", "timeout"},
    "dec-independent": {"rounds", "mode", "transport", "timeout"},
    "dec-sequential": {"p_loss", "delay", "comm_range", "transport", "timeout"},
}

# ------------------------------------------------------------------------- the oracle

INF = math.inf
#: Key -> its allowed range (RANGES by name, or the settings' own rules).
KEY_RANGES: dict[str, Range] = {
    **{k: RANGES[k] for k in ("dt", "process_noise", "speed", "heading", "turn_hold",
                              "max_turn_rate", "fov_half_angle", "max_turn", "depression",
                              "beamwidth", "snr_ref_db", "range_ref", "range_resolution",
                              "monopulse_slope", "clutter_rate", "altitude", "birth_rate")},
    "width": RANGES["length"], "moves": RANGES["length"],
    "false_alarm_probability": RANGES["probability"],
    "min_ground_range": RANGES["ground_range"], "max_ground_range": RANGES["ground_range"],
    "speed_range": RANGES["speed"], "mode_process_noise": RANGES["process_noise"],
    "cov": RANGES["covariance"],
    "heading_deg": Range(None, 360.0, magnitude=True),
    "fov_half_angle_deg": Range(0.0, 180.0, lo_open=True),
    "max_turn_deg": Range(0.0, 180.0), "depression_deg": Range(0.0, 90.0, lo_open=True),
    "max_turn_rate_deg": Range(0.0, 180.0),
    "horizon": Range(1, 1000), "steps_per_epoch": Range(1, 1000),
    "steps": Range(1, 100_000), "runs": Range(1, 100_000), "seed": Range(0, None),
    "max_inner": Range(1, None), "max_outer": Range(1, None), "max_plans": Range(1, None),
    "rounds": Range(1, None), "delay": Range(0, None), "initial_targets": Range(0, None),
    "alpha": Range(0.0, 1.0, lo_open=True, hi_open=True),
    "beta": Range(0.0, 1.0, lo_open=True, hi_open=True),
    "p_loss": Range(0.0, 1.0), "comm_range": Range(0.0, None, lo_open=True),
    "gate_probability": Range(0.0, 1.0, lo_open=True, hi_open=True),
    "survival_probability": Range(0.0, 1.0, lo_open=True),
    "timeout": Range(0.0, None, lo_open=True),
}
INT_KEYS = {"horizon", "steps_per_epoch", "steps", "runs", "seed", "max_inner", "max_outer",
            "max_plans", "rounds", "delay", "initial_targets"}
#: Keys where an infinity is a valid value.
INF_OK = {"comm_range"}
ENUMS: dict[str, tuple[str, ...]] = {
    "visibility": ("probabilistic", "mean"), "objective": ("cumulative", "terminal"),
    "planning_detection": ("aware", "ignore"), "planning_occlusion": ("aware", "ignore"),
    "execution": ("ol", "olf"), "miss_update": ("negative", "none"), "model": ("cv", "imm"),
    "association": ("pda", "nearest"), "detection": ("ideal", "swerling1"),
    "births": ("none", "edges", "uniform"), "scripted": ("williams15", "vo12"),
    "design": ("star", "full"), "mode": ("jsfp", "best-response"),
    "transport": ("inproc", "bus"), "preset": ("paper", "radar", "urban", "swarm"),
    "feature": ("sensor_speed", "min_ground_range", "town", "snr_ref_db", "clutter_rate",
                "setting"),
    "name": BUILTIN_PLANNERS, "planner": BUILTIN_PLANNERS,
}
#: Lists of a fixed length: any change of shape is refused.
FIXED_LISTS = {"position", "mean", "cov", "target_box", "speed_range", "sensor_box", "box"}
#: Text that may be anything (so a new string is no reason to refuse).
FREE_TEXT = {"description", "label", "file", "key", "method", "reference"}


@dataclass
class Expect:
    """What a case must give. Each change that must be refused by itself is a reason, with
    the fields that may name it; a case with a reason must end in exit 2, and unless some
    other change's effect is unknown (``open``), its error line must name one of the
    reasons' fields (or a field inside or around one of them)."""

    reasons: list[tuple[set[str], str]] = field(default_factory=list)
    open: bool = False

    @property
    def refuse(self) -> bool:
        return bool(self.reasons)

    @property
    def fields(self) -> set[str] | None:
        return None if self.open else set().union(*(f for f, _ in self.reasons))

    @property
    def why(self) -> list[str]:
        return [w for _, w in self.reasons]

    def unknown(self) -> None:
        self.open = True

    def bad(self, fields: set[str], why: str) -> None:
        self.reasons.append((set(fields), why))

    def drop(self, prefixes: set[str]) -> None:
        """Forget the reasons in file values that an option replaces (never read)."""
        def masked(f: str) -> bool:
            return any(f == p or f.startswith(p + ".") or f.startswith(p + "[")
                       for p in prefixes)
        kept = [(f, w) for f, w in self.reasons
                if not all(masked(x) or x.startswith("FILE") for x in f)]
        if len(kept) < len(self.reasons):
            self.open = True            # what the masked change did is not known
        self.reasons = kept


def dotted(path: tuple[Any, ...], prefix: str = "") -> str:
    out = prefix
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (("." if out else "") + str(p))
    return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _key_of(path: tuple[Any, ...]) -> tuple[str, Any]:
    """The nearest string key of a path and the index below it (``moves[0]`` -> moves, 0)."""
    for i in range(len(path) - 1, -1, -1):
        if isinstance(path[i], str):
            return path[i], path[i + 1] if i + 1 < len(path) else None
    return "", None


def _range_of(path: tuple[Any, ...]) -> Range | None:
    key, index = _key_of(path)
    if key == "height":
        return RANGES["building_height"] if "buildings" in path else RANGES["length"]
    if key == "mean" and isinstance(index, int):
        return RANGES["coordinate"] if index < 2 else RANGES["velocity"]
    if key == "values" or "axes" in path:
        return None
    return KEY_RANGES.get(key)


def text_level(v: Any, json_doc: bool) -> bool:
    """Whether a value makes the whole file unreadable whatever its place: deep nesting,
    an integer of more than 4,300 digits, a lone surrogate (TOML), a non-finite number
    (JSON: ``NaN``, ``Infinity``)."""
    if isinstance(v, fz.Raw):
        return True
    if isinstance(v, str):
        return not json_doc and any("\ud800" <= c <= "\udfff" for c in v)
    if isinstance(v, float):
        return json_doc and not math.isfinite(v)
    if isinstance(v, dict):
        return any(text_level(k, json_doc) or text_level(x, json_doc) for k, x in v.items())
    if isinstance(v, list):
        return any(text_level(x, json_doc) for x in v)
    return False


def judge_mutation(m: dict[str, Any], expect: Expect, prefix: str, json_doc: bool,
                   known_keys: set[str]) -> None:
    """Fold one mutation record of ``fuzz_docs.mutate`` into ``expect``."""
    if text_level(m.get("new"), json_doc) or (m["kind"] == "shape"
                                              and text_level(m["old"], json_doc)):
        before = len(expect.reasons)
        _judge(m, expect, prefix, json_doc, known_keys)
        for fields, _ in expect.reasons[before:]:
            fields.add("FILE")          # the file is refused before its fields are read
        return
    _judge(m, expect, prefix, json_doc, known_keys)


def _judge(m: dict[str, Any], expect: Expect, prefix: str, json_doc: bool,
           known_keys: set[str]) -> None:
    kind, path = m["kind"], tuple(m["path"])
    here = dotted(path, prefix)
    key, _ = _key_of(path)
    if kind == "root":
        expect.bad({"FILE"}, "the document is not a table")
    elif kind == "duplicate":
        expect.bad({here, "FILE"}, f"{here} written twice")
    elif kind == "add":
        name = path[-1]
        if name not in known_keys and not m.get("existed"):
            expect.bad({here, dotted(path[:-1], prefix) or "FILE"}, f"unknown key {here}")
        else:
            expect.unknown()
    elif kind == "shape":
        if m["choice"] == "listed" or (key in FIXED_LISTS and isinstance(m["old"], list)):
            expect.bad({here}, f"{here} changed shape ({m['choice']})")
        elif m["choice"] == "wrap" and m["old"] and all(_is_number(x) for x in m["old"]):
            expect.bad({here}, f"{here} wrapped in a list")
        else:
            expect.unknown()
    elif kind == "degrees":
        # path: (..., table, name); the angle written under the radian key.
        name, table = path[-1], path[:-1]
        in_sensor = len(table) >= 2 and table[-2] == "sensors"
        in_target = len(table) >= 2 and table[-2] == "targets" and not json_doc
        allowed = ({"fov_half_angle", "max_turn", "depression", "beamwidth"} if in_sensor
                   else {"max_turn_rate"} if in_target else set())
        rng = KEY_RANGES.get(name)
        if m.get("both") or m.get("deg_existed"):
            expect.bad({here, here + "_deg"}, f"{here} in radians and in degrees")
        elif name not in allowed:
            expect.bad({here, dotted(table, prefix)}, f"{here}: not a key of that table")
        elif rng is not None and not rng.contains(m["new"]):
            expect.bad({here}, f"{here} = {m['new']} (degrees as radians)")
        else:
            expect.unknown()
    elif kind == "replace":
        old, new = m["old"], m["new"]
        if isinstance(new, fz.Raw):
            expect.bad({here, "FILE"}, f"{here}: deep nesting or a huge integer")
        elif isinstance(old, dict):
            if not isinstance(new, dict) or new == {"a": 1}:
                expect.bad({here, here + ".a"}, f"{here}: a table replaced")
            else:
                expect.unknown()
        elif isinstance(old, list):
            if not isinstance(new, list):
                expect.bad({here}, f"{here}: a list replaced by {type(new).__name__}")
            else:
                expect.unknown()
        elif isinstance(old, bool):
            if not isinstance(new, bool):
                expect.bad({here}, f"{here}: a flag replaced")
        elif _is_number(old):
            rng = _range_of(path)
            if new is None and not json_doc:
                expect.bad({here}, f"{here} = '' (TOML has no null)")
            elif new is None and len(path) == 2 and path[0] == "planner":
                # A planner setting's null is its default (planners.registry.check_settings).
                expect.unknown()
            elif not _is_number(new):
                if "axes" in path and isinstance(new, str):
                    expect.unknown()
                else:
                    expect.bad({here}, f"{here}: a number replaced by {_short(new)}")
            elif isinstance(new, float) and math.isnan(new):
                expect.bad({here}, f"{here} = nan")
            elif isinstance(new, float) and math.isinf(new):
                if key in INF_OK and new > 0 or "axes" in path:
                    expect.unknown()
                else:
                    expect.bad({here}, f"{here} = {new}")
            elif key in INT_KEYS and isinstance(new, float) and "axes" not in path:
                expect.bad({here}, f"{here} = {new}: not an integer")
            elif rng is not None and not rng.contains(new):
                expect.bad({here}, f"{here} = {_short(new)}: outside {rng.text()}")
            elif isinstance(new, int) and abs(new) > 1e308 and key not in INT_KEYS:
                expect.bad({here}, f"{here}: an integer no float can hold")
            else:
                expect.unknown()
        elif isinstance(old, str):
            if not isinstance(new, str):
                expect.bad({here}, f"{here}: a string replaced by {_short(new)}")
            elif key in FREE_TEXT or "axes" in path or (key == "name" and "methods" in path):
                expect.unknown()
            elif key == "kind":
                kinds = ("known",) if "tracker" in path else ("cv", "dubins")
                if new not in kinds:
                    expect.bad({here}, f"{here} = {_short(new)}: unknown kind")
            elif key in ENUMS and new not in ENUMS[key]:
                expect.bad({here}, f"{here} = {_short(new)}: not one of {ENUMS[key]}")
            else:
                expect.unknown()
        else:
            expect.unknown()
    else:   # delete
        expect.unknown()


def _short(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def known_keys() -> set[str]:
    """Every key name a file may hold (the file models' fields and the planners'
    settings), so that an added key is known to be unknown."""
    import dataclasses
    import importlib
    import inspect
    import pkgutil

    from pydantic import BaseModel

    import sensorplan.config
    from sensorplan.planners.registry import PLANNERS

    modules = [f"sensorplan.config.{m.name}"
               for m in pkgutil.iter_modules(sensorplan.config.__path__)]
    modules += ["sensorplan.study.file", "sensorplan.study.grid", "sensorplan.study.model"]
    names: set[str] = set()
    for mod_name in modules:
        try:
            mod = importlib.import_module(mod_name)
        except ImportError:
            continue
        for obj in vars(mod).values():
            if inspect.isclass(obj) and issubclass(obj, BaseModel):
                names |= set(obj.model_fields)
    for name in list(PLANNERS):
        try:
            names |= {f.name for f in dataclasses.fields(PLANNERS[name])}
        except Exception:   # noqa: BLE001 - a plugin that cannot be loaded adds nothing
            pass
    for d in (fz.PLAN_DOC, fz.SCENARIO_DOC, fz.STUDY_DOC, fz.GRID_DOC, fz.PLAN_DOC_NEW,
              fz.SCENARIO_DOC_NEW, fz.STUDY_DOC_NEW, fz.AGENTS_DOC, *fz.GRID_AXES):
        names |= {str(p[-1]) for p in fz.paths(d) if isinstance(p[-1], str)}
    return names


def field_matches(reported: str, wanted: str, files: set[str]) -> bool:
    """Whether an error's field names ``wanted`` (or a field inside or around it)."""
    if wanted == "FILE":
        return reported in files or any(reported.endswith(f) for f in files)
    r, w = _norm(reported), _norm(wanted)
    if r == w:
        return True
    for a, b in ((r, w), (w, r)):
        if a.startswith(b + ".") or a.startswith(b + "["):
            return True
    # A study or grid names a field of its scenario file through the study's own path.
    return r.endswith("." + w) or r.endswith("]" + w) or w.endswith("." + r)


def _norm(f: str) -> str:
    return f.strip().strip("'\"")


# -------------------------------------------------------------------------- options

#: Option -> (valid values, invalid values). A value None means a flag without one.
RUN_OPTIONS: dict[str, tuple[list[Any], list[Any]]] = {
    "--horizon": ([1, 2], [0, -1, 1001, 2.5, "x", 10**30, ""]),
    "--steps-per-epoch": ([1, 2], [0, 1001, "two", -3]),
    "--execution": (["ol", "olf"], ["closed", "OLF", ""]),
    "--visibility": (["probabilistic", "mean"], ["always", "Mean"]),
    "--objective": (["cumulative", "terminal"], ["sum", ""]),
    "--planning-detection": (["aware", "ignore"], ["on", "aware "]),
    "--planning-occlusion": (["aware", "ignore"], ["off", "yes"]),
    "--seed": ([0, 7, 2**40], [-1, "x", 1.5, 2**200 * -1]),
    "--tracker": (["known"], ["pmb", "KNOWN", "", "gm-phd", "known "]),
    "--miss-update": (["negative", "none"], ["positive", "None"]),
    "--tracker-model": (["cv", "imm"], ["ca", "IMM"]),
    "--tracker-q": ([0, 1, 0.5, 1e6], [-1, "nan", "inf", 1e7, "x", "-inf"]),
    "--gate-probability": ([0.5, 0.999], [0, 1, 1.5, "nan", -0.1]),
    "--association": (["pda", "nearest"], ["jpda", "PDA"]),
}
FLAGS = ["--gate", "--no-gate", "--reacquire", "--no-reacquire", "--known-map",
         "--no-known-map"]
AGENT_OPTIONS: dict[str, tuple[list[Any], list[Any]]] = {
    "--transport": (["inproc"], ["tcp", "", "BUS"]),
    "--rounds": ([1, 5, 50], [0, -1, "x", 2.5]),
    "--p-loss": ([0, 0.1, 1], [-0.1, 1.5, "nan", "x"]),
    "--delay": ([0, 1, 3], [-1, 1.5, "x"]),
    "--comm-range": (["inf", 100, 1e9], [0, -1, "nan", "x"]),
    "--agent-mode": (["jsfp", "best-response"], ["br", "JSFP"]),
}
AGENT_SETTING = {"--rounds": "rounds", "--p-loss": "p_loss", "--delay": "delay",
                 "--comm-range": "comm_range", "--agent-mode": "mode",
                 "--transport": "transport"}
SHORT = {"--horizon": "-K", "--steps-per-epoch": "-e", "--steps": "-n", "--out": "-o"}
#: Options that override a file key: (section, key).
OPTION_KEYS = {"--horizon": ("planning", "horizon"), "--steps-per-epoch":
               ("planning", "steps_per_epoch"), "--execution": ("planning", "execution"),
               "--visibility": ("planning", "visibility"),
               "--objective": ("planning", "objective"),
               "--planning-detection": ("planning", "planning_detection"),
               "--planning-occlusion": ("planning", "planning_occlusion"),
               "--seed": ("run", "seed"), "--steps": ("run", "steps"),
               "--tracker": ("tracker", "kind"), "--miss-update": ("tracker", "miss_update"),
               "--tracker-model": ("tracker", "model"),
               "--tracker-q": ("tracker", "process_noise"),
               "--gate-probability": ("tracker", "gate_probability"),
               "--association": ("tracker", "association"),
               "--gate": ("tracker", "gate"), "--no-gate": ("tracker", "gate"),
               "--reacquire": ("tracker", "reacquire"),
               "--no-reacquire": ("tracker", "reacquire"),
               "--known-map": ("tracker", "known_map"),
               "--no-known-map": ("tracker", "known_map"),
               "--planner": ("planning", "planner")}
UNKNOWN_OPTIONS = ["--horizn", "--bogus", "--steps-per-epochs", "--tracker-kind", "--K"]


def _text(v: Any) -> str:
    return v if isinstance(v, str) else repr(v) if isinstance(v, float) else str(v)


# ----------------------------------------------------------------------------- cases


@dataclass
class Case:
    kind: str
    index: int
    command: str
    args: list[str]
    files: dict[str, bytes]
    done: list[str]
    expect: Expect
    interrupt_after: float | None = None
    closed_stdout: bool = False
    success_files: list[str] = field(default_factory=list)
    env: dict[str, str] = field(default_factory=dict)
    agent_settings: set[str] = field(default_factory=set)


class Draw:
    """Draws for one case, from hypothesis strategies seeded by ``SEED:KIND:i``."""

    def __init__(self, seed: str) -> None:
        self.data = ConjectureData(random=random.Random(seed))

    def __call__(self, strategy: st.SearchStrategy[Any]) -> Any:
        return self.data.draw(strategy)

    def pick(self, seq: Any) -> Any:
        return self(st.sampled_from(list(seq)))

    def chance(self, p: float) -> bool:
        return self(st.integers(0, 999)) < int(p * 1000)

    def int(self, lo: int, hi: int) -> int:
        return self(st.integers(lo, hi))


def mutated(draw: Draw, base: dict[str, Any], json_doc: bool, focus: tuple[str, ...],
            expect: Expect, prefix: str, keys: set[str], done: list[str], name: str,
            damage: float = 0.1) -> bytes:
    """A mutated document's bytes; its mutations folded into ``expect`` (``FILE`` -> name).
    One document in eight is left valid, so that the options and the runs themselves are
    tried too."""
    if draw.chance(0.125):
        done.append(f"{name}: unmutated")
        expect.unknown()
        return (fz.to_json(base) if json_doc else fz.to_toml(base)).encode()
    log: list[dict[str, Any]] = []
    doc, did = draw(fz.mutate(base, json_doc, focus=focus, log=log))
    done += [f"{name}: {d}" for d in did]
    kept: list[dict[str, Any]] = []
    for m in log:      # a later change at or above an earlier one's path undoes it
        p = tuple(m["path"])
        kept = [k for k in kept if tuple(k["path"])[:len(p)] != p]
        kept.append(m)
    for m in kept:
        judge_mutation(m, expect, prefix, json_doc, keys)
    for fields, _ in expect.reasons:
        if "FILE" in fields:
            fields.discard("FILE")
            fields.add(f"FILE:{name}")
    text = fz.to_json(doc) if json_doc else fz.to_toml(doc)
    data = text.encode("utf-8", "surrogatepass")
    if draw.chance(damage):
        data, how = draw(fz.damaged(text))
        done.append(f"{name}: {how}")
        if how == "text empty":
            expect.bad({f"FILE:{name}"}, "an empty file")
        else:
            expect.unknown()
    return data


def out_place(draw: Draw, case: Case, option: str = "--out") -> None:
    """``--out`` fresh (usually) or a place that cannot be written."""
    how = draw.pick(["fresh"] * 17 + ["file", "under-file", "devnull", "proc", "long", "dot",
                                      "full"])
    case.done.append(f"{option}: {how}")
    if how == "fresh":
        case.args += [draw.pick([option, SHORT.get(option, option)]), "out"]
        case.success_files.append("out")
        return
    if how == "file":
        case.files["taken"] = b"a file\n"
        case.args += [option, "taken"]
    elif how == "under-file":
        case.files["taken"] = b"a file\n"
        case.args += [option, "taken/out"]
    elif how == "devnull":
        case.args += [option, "/dev/null"]
    elif how == "proc":
        case.args += [option, "/proc/sensorplan-fuzz/out"]
    elif how == "long":
        case.args += [option, "d" * 300]
    elif how == "dot":
        case.args += [option, "."]
        return                                 # the case directory: maybe fine, maybe not
    else:                                       # the figure's file linked to /dev/full
        case.files["@full"] = b""
        case.args += [option, "out"]
        return
    case.expect.bad({option}, f"{option}: {how}")


def run_options(draw: Draw, case: Case, overridden: set[tuple[str, str]],
                agents: bool) -> None:
    """0 to 4 of the run-setting options, valid or not; a flag now and then."""
    table = dict(RUN_OPTIONS)
    if agents:
        table.update(AGENT_OPTIONS)
    for _ in range(draw.int(0, 4)):
        roll = draw.int(0, 19)
        if roll == 0:
            opt = draw.pick(UNKNOWN_OPTIONS)
            case.args += [opt, "1"]
            case.expect.bad({opt}, f"unknown option {opt}")
            case.done.append(f"{opt} 1")
            continue
        if roll <= 2:
            flag = draw.pick(FLAGS)
            case.args.append(flag)
            case.done.append(flag)
            overridden.add(OPTION_KEYS[flag])
            if flag == "--no-gate":
                case.expect.unknown()     # refused unless re-acquisition is off too
            if draw.chance(0.2):                    # "--gate false": a flag given a value
                case.args.append("false")
                case.done.append("(a value after the flag)")
                case.expect.bad({"false", flag}, f"{flag} given a value")
            continue
        opt = draw.pick(sorted(table))
        valid, invalid = table[opt]
        good = draw.chance(0.7)
        value = draw.pick(valid if good else invalid)
        name = draw.pick([opt, SHORT.get(opt, opt)])
        case.args += [name, _text(value)]
        case.done.append(f"{name} {_text(value)!r}")
        if opt in OPTION_KEYS:
            overridden.add(OPTION_KEYS[opt])
        if opt in AGENT_SETTING:
            case.agent_settings.add(AGENT_SETTING[opt])
        if not good:
            case.expect.bad({opt, name}, f"{name} {_text(value)!r}")


def unmask(case: Case, overridden: set[tuple[str, str]]) -> None:
    """A file value an option overrides is never read: its mutation proves nothing."""
    case.expect.drop({f"{sec}.{key}" for sec, key in overridden})


def scenario_case(draw: Draw, case: Case, keys: set[str], agents: bool) -> None:
    """simulate or agents: a file or a preset, options, an output place, signals."""
    which = draw.pick(["new"] * 5 + ["old"] * 2 + ["births", "scripted", "preset",
                                                   "preset", "extreme"])
    if agents and which in ("new", "old"):
        which = draw.pick(["agents", "agents", which])
    base = {"new": fz.SCENARIO_DOC_NEW, "old": fz.SCENARIO_DOC, "births":
            fz.SCENARIO_DOC_BIRTHS, "scripted": fz.SCENARIO_DOC_SCRIPTED,
            "agents": fz.AGENTS_DOC}.get(which)
    overridden: set[tuple[str, str]] = set()
    file_planner: str | None = None
    if which == "preset":
        preset = draw.pick(["paper", "radar", "urban", "paper", "Paper", "", "swam"])
        case.args += ["--preset", preset]
        case.done.append(f"--preset {preset!r}")
        if preset not in ("paper", "radar", "urban"):
            case.expect.bad({"--preset"}, "an unknown preset")
        file_planner = "pg"
    elif which == "extreme":
        doc = draw(fz.extreme_scenario())
        case.files["scenario.toml"] = fz.to_toml(doc).encode()
        case.args.append("scenario.toml")
        case.done.append("a valid scenario with every value at an extreme of its range")
        case.expect.unknown()
        file_planner = doc["planning"]["planner"]
    else:
        assert base is not None
        if which in ("births", "scripted"):
            case.expect.unknown()        # refused whatever: the tracker knows its targets
        case.files["scenario.toml"] = mutated(draw, base, False, fz.NEW_KEYS, case.expect, "",
                                              keys, case.done, "scenario.toml")
        case.args.append("scenario.toml")
        file_planner = str(base.get("planning", {}).get("planner", "pg"))
    # The planner.
    if agents:
        if draw.chance(0.5):
            name = draw.pick(list(DEC_PLANNERS) * 3 + ["pg", "annealing", "dec-jsf"])
            case.args += ["--planner", name]
            case.done.append(f"--planner {name}")
            overridden.add(("planning", "planner"))
            if name not in DEC_PLANNERS:
                case.expect.bad({"--planner"}, f"agents --planner {name}")
            planner = name
        else:
            planner = file_planner if file_planner in DEC_PLANNERS else "dec-jsfp"
        if draw.chance(0.06):
            case.args += ["--transport", "bus"]
            case.done.append("--transport bus")
    else:
        if draw.chance(0.25):
            name = draw.pick(["pg", "random", "sequential-greedy", "pg-refine", "dec-jsfp",
                              "annealing", "pg-refin", "os:system", ""])
            case.args += ["--planner", name]
            case.done.append(f"--planner {name!r}")
            overridden.add(("planning", "planner"))
            if name not in BUILTIN_PLANNERS:
                case.expect.bad({"--planner"}, f"--planner {name!r}")
    run_options(draw, case, overridden, agents)
    if agents:
        for s in case.agent_settings:
            if s not in DEC_SETTINGS.get(planner, set()):
                opt = next(o for o, k in AGENT_SETTING.items() if k == s)
                case.expect.bad({opt}, f"{opt} not a setting of {planner}")
    # A short run, unless the steps are what is being tried.
    if not any(a in ("--steps", "-n") for a in case.args):
        steps = draw.pick([1, 2, 3, 3] + ([0, -1, 100_001, "x"] if draw.chance(0.1) else []))
        case.args += [draw.pick(["--steps", "-n"]), str(steps)]
        case.done.append(f"--steps {steps}")
        if steps not in (1, 2, 3):
            case.expect.bad({"--steps"}, f"--steps {steps}")
    overridden.add(("run", "steps"))
    unmask(case, overridden)
    if not agents and draw.chance(0.05):
        case.args.append("--animate")
        fmt = draw.pick([None, None, "gif", "mp4", "avi"])
        if fmt:
            case.args += ["--animation-format", fmt]
            if fmt != "gif":
                case.expect.unknown() if fmt == "mp4" else case.expect.bad(
                    {"--animation-format"}, f"--animation-format {fmt}")
        case.done.append(f"--animate {fmt or ''}")
    out_place(draw, case)
    if case.success_files == ["out"]:
        case.success_files = ["out/episode.npz", "out/episode.png"] + (
            ["out/agents.json"] if agents else [])
    signals(draw, case)


def signals(draw: Draw, case: Case) -> None:
    roll = draw.int(0, 99)
    if roll < 4:
        case.interrupt_after = draw(st.floats(0.5, 8.0))
        case.done.append(f"Ctrl-C after {case.interrupt_after:.1f} s")
    elif roll < 8:
        case.closed_stdout = True
        case.done.append("stdout closed")


def plan_case(draw: Draw, case: Case, keys: set[str]) -> None:
    family = draw.int(0, 99)
    if family < 8:
        doc = draw(fz.extreme_plan())
        case.files["problem.json"] = fz.to_json(doc).encode()
        case.done.append("a valid decision with every value at an extreme of its range")
        case.expect.unknown()
    else:
        base = dict(draw.pick([fz.PLAN_DOC, fz.PLAN_DOC_NEW, fz.PLAN_DOC_NEW]))
        planner = draw.pick(["keep"] * 4 + ["random", "sequential-greedy", "pg-refine",
                                            "brute-force", "dec-jsfp", "dec-sequential",
                                            "dec-independent"])
        if planner != "keep":
            params: dict[str, Any] = {"name": planner, "seed": 1}
            if planner == "brute-force":
                params["max_plans"] = 200_000
                base["horizon"] = 1
            if planner in ("dec-jsfp", "dec-independent"):
                params["rounds"] = 40
            if planner in ("dec-jsfp", "dec-sequential"):
                params["p_loss"] = 0.2
            base["planner"] = params
            case.done.append(f"planner {planner}")
        focus = fz.NEW_KEYS + ("heading", "planner", "name") if draw.chance(0.5) else ()
        case.files["problem.json"] = mutated(draw, base, True, focus, case.expect, "", keys,
                                             case.done, "problem.json")
    case.args += ["problem.json"]
    if draw.chance(0.12):
        name = draw.pick(["pg", "random", "sequential-greedy", "pg-refine", "dec-jsfp",
                          "annealing", "pg-refin", "Random", "", "sensorplan.planners:nothing"])
        case.args += ["--planner", name]
        case.done.append(f"--planner {name!r}")
        # The file's settings the new planner does not take are dropped: their mutations
        # prove nothing.
        case.expect.drop({"planner"})
        if name not in BUILTIN_PLANNERS:
            case.expect.bad({"--planner"}, f"--planner {name!r}")
    if draw.chance(0.03):
        case.closed_stdout = True
        case.done.append("stdout closed")


SCENARIO_FILE_FOR_STUDY = {**fz.SCENARIO_DOC_NEW}


def study_case(draw: Draw, case: Case, keys: set[str], grid: bool) -> None:
    if grid:
        base = dict(fz.GRID_DOC)
        axes = [dict(a) for a in base["axes"]]
        if draw.chance(0.6):
            axes = [dict(draw.pick(fz.GRID_AXES)) for _ in range(draw.int(1, 2))]
            feats = [(a["feature"], a.get("key")) for a in axes]
            if len(set(feats)) < len(feats):
                axes = axes[:1]
            case.done.append("axes " + ", ".join(f"{a['feature']}:{a.get('key', '')}"
                                                 for a in axes))
        base["axes"] = axes
        if draw.chance(0.3):
            base["design"] = "full"
        name = "grid.toml"
    else:
        base = dict(draw.pick([fz.STUDY_DOC, fz.STUDY_DOC_NEW, fz.STUDY_DOC_NEW]))
        name = "study.toml"
    use_file = draw.chance(0.3)
    if use_file:
        base["scenario"] = {"file": "scenario.toml"}
    mutate_scenario = use_file and draw.chance(0.4)
    if mutate_scenario:
        case.files[name] = fz.to_toml(base).encode()
        case.files["scenario.toml"] = mutated(draw, SCENARIO_FILE_FOR_STUDY, False,
                                              fz.NEW_KEYS, case.expect, "", keys, case.done,
                                              "scenario.toml")
    else:
        if use_file:
            case.files["scenario.toml"] = fz.to_toml(SCENARIO_FILE_FOR_STUDY).encode()
        focus = (fz.NEW_KEYS + (("axes", "values", "base", "feature", "key", "design",
                                 "comparisons") if grid else ("methods", "planner_params")))
        case.files[name] = mutated(draw, base, False, focus, case.expect, "", keys,
                                   case.done, name)
    case.args.append(name)
    out_place(draw, case)
    if case.success_files == ["out"]:
        case.success_files = ["out/grid.json"] if grid else ["out/steps.parquet"]
    roll = draw.int(0, 99)
    if roll < 80:
        case.args += [draw.pick(["--workers", "-j"]), "1"]
    elif roll < 86:
        case.args += ["--workers", "2"]
        case.done.append("--workers 2")
    elif roll < 92:
        w = draw.pick(["0", "-1", "x", "1.5", ""])
        case.args += ["--workers", w]
        case.done.append(f"--workers {w!r}")
        case.expect.bad({"--workers", "-j"}, f"--workers {w!r}")
    elif roll < 94:
        case.args += ["--workers", "1", "--scheduler", "local"]
        case.done.append("--scheduler local")
    else:
        s = draw.pick(["foo://bar", "", "tcp://", "local ", "tcp://999.1.1.1:1"])
        case.args += ["--workers", "1", "--scheduler", s]
        case.done.append(f"--scheduler {s!r}")
        case.expect.bad({"--scheduler"}, f"--scheduler {s!r}")
    signals(draw, case)


def valid_scenario_case(draw: Draw, case: Case, agents: bool) -> None:
    """A run that must succeed (or be refused by a documented joint rule): a valid file or
    a preset, valid options only, a fresh output place; Ctrl-C and a closed stdout as in
    the other cases."""
    case.expect.unknown()
    which = draw.pick(["new", "old", "agents", "extreme", "preset"])
    if which == "preset":
        case.args += ["--preset", draw.pick(["paper", "radar", "urban"])]
    else:
        doc = draw(fz.extreme_scenario()) if which == "extreme" else {
            "new": fz.SCENARIO_DOC_NEW, "old": fz.SCENARIO_DOC, "agents": fz.AGENTS_DOC}[which]
        case.files["scenario.toml"] = fz.to_toml(doc).encode()
        case.args.append("scenario.toml")
    case.done.append(f"valid run: {which}")
    if agents:
        if draw.chance(0.7):
            case.args += ["--planner", draw.pick(DEC_PLANNERS)]
        if draw.chance(0.1):
            case.args += ["--transport", "bus"]
    elif draw.chance(0.6):
        case.args += ["--planner", draw.pick([p for p in BUILTIN_PLANNERS
                                              if p != "brute-force"])]
    table = dict(RUN_OPTIONS)
    if agents:
        planner = next((case.args[i + 1] for i, a in enumerate(case.args)
                        if a == "--planner"), "dec-jsfp")
        table.update({o: v for o, v in AGENT_OPTIONS.items()
                      if o != "--transport" and AGENT_SETTING[o] in DEC_SETTINGS[planner]})
    for _ in range(draw.int(0, 5)):
        opt = draw.pick(sorted(table))
        case.args += [opt, _text(draw.pick(table[opt][0]))]
    if draw.chance(0.3):
        case.args.append(draw.pick(["--no-known-map", "--gate", "--no-reacquire"]))
    case.args += ["--steps", str(draw.int(1, 6)), "--out", "out"]
    case.done.append(" ".join(case.args[1:]))
    case.success_files = ["out/episode.npz", "out/episode.png"] + (
        ["out/agents.json"] if agents else [])
    if not agents and draw.chance(0.05):
        case.args.append("--animate")
    signals(draw, case)


def valid_method(draw: Draw, i: int) -> dict[str, Any]:
    """A study method with a valid planner, horizon and tracker settings."""
    planner = draw.pick(BUILTIN_PLANNERS)
    m: dict[str, Any] = {"name": f"m{i} {planner}", "planner": planner}
    params: dict[str, Any] = {}
    if planner in ("pg", "pg-refine"):
        params = {"max_inner": draw.int(1, 10), "max_outer": draw.int(1, 3)}
    elif planner == "brute-force":
        params = {"max_plans": 2_000_000}
    elif planner in DEC_PLANNERS:
        settings = DEC_SETTINGS[planner]
        if "rounds" in settings:
            params["rounds"] = draw.int(1, 30)
        if "p_loss" in settings:
            params["p_loss"] = draw.pick([0.0, 0.3, 1.0])
            params["delay"] = draw.int(0, 2)
            params["comm_range"] = draw.pick([50.0, 400.0, float("inf")])
        if "mode" in settings:
            params["mode"] = draw.pick(["jsfp", "best-response"])
    if params:
        m["planner_params"] = params
    if planner != "brute-force":
        m["horizon"] = draw.int(1, 2)
    m["steps_per_epoch"] = draw.int(1, 2)
    m["execution"] = draw.pick(["ol", "olf"])
    m["visibility"] = draw.pick(["probabilistic", "mean"])
    m["objective"] = draw.pick(["cumulative", "terminal"])
    tracker: dict[str, Any] = {"kind": "known",
                               "miss_update": draw.pick(["negative", "none"]),
                               "model": draw.pick(["cv", "imm"]),
                               "association": draw.pick(["pda", "nearest"])}
    if draw.chance(0.3):
        tracker.update(gate=False, reacquire=False)
    m["tracker"] = tracker
    return m


def valid_study_case(draw: Draw, case: Case, grid: bool) -> None:
    """A small study or grid that must succeed: valid methods over a preset or the newer
    scenario file, with 1 or 2 workers."""
    case.expect.unknown()
    doc: dict[str, Any] = {"description": "valid", "runs": draw.int(1, 2),
                           "steps": draw.int(2, 4), "seed": draw.int(0, 99)}
    if draw.chance(0.3):
        doc["scenario"] = {"file": "scenario.toml"}
        case.files["scenario.toml"] = fz.to_toml(fz.SCENARIO_DOC_NEW).encode()
    else:
        doc["scenario"] = {"preset": draw.pick(["paper", "radar", "urban"])}
    doc["methods"] = [valid_method(draw, i) for i in range(draw.int(1, 3))]
    name = "study.toml"
    if grid:
        name = "grid.toml"
        axes = [dict(draw.pick(fz.GRID_AXES)) for _ in range(draw.int(1, 2))]
        if len({(a["feature"], a.get("key")) for a in axes}) < len(axes):
            axes = axes[:1]
        if any(a.get("key") == "planner_params.rounds" for a in axes) and not any(
                "rounds" in m.get("planner_params", {}) for m in doc["methods"]):
            axes = [a for a in axes if a.get("key") != "planner_params.rounds"] or [
                dict(fz.GRID_AXES[0])]
        if any(a.get("key") == "horizon" for a in axes):
            for m in doc["methods"]:
                if m["planner"] == "brute-force":
                    m["planner"] = "random"
                    m.pop("planner_params", None)
        doc["axes"] = axes
        doc["design"] = draw.pick(["star", "full"])
        # A grid compares methods: with no myopic or random reference to fall back on,
        # it needs [[comparisons]] (and a second method to compare with).
        if len(doc["methods"]) == 1:
            doc["methods"].append({"name": "reference", "planner": "random"})
        doc["comparisons"] = [{"method": doc["methods"][0]["name"],
                               "reference": doc["methods"][1]["name"]}]
    case.files[name] = fz.to_toml(doc).encode()
    case.args += [name, "--out", "out", "--workers", draw.pick(["1", "1", "2"])]
    case.done.append(f"valid {'grid' if grid else 'study'}: " + ", ".join(
        m["name"] for m in doc["methods"]))
    case.success_files = ["out/grid.json"] if grid else ["out/steps.parquet"]
    signals(draw, case)


def build(kind: str, seed: int, index: int, keys: set[str], valid_share: float = 0.0
          ) -> Case:
    """Case ``index`` of ``kind`` under ``seed``; a draw that runs out of room is drawn
    again under a derived seed. ``valid_share``: the share of cases that are valid runs
    (no mutation, valid options: what must work is tried too)."""
    for attempt in range(20):
        tag = f"{seed}:{kind}:{index}" + (f":{attempt}" if attempt else "")
        draw = Draw(tag)
        command = "agents" if kind == "agents" else kind
        case = Case(kind, index, command, [command], {}, [], Expect())
        try:
            # Hypothesis' internal draws outside a test (its strategies need a context).
            with BuildContext(draw.data, wrapped_test=lambda: None):
                if valid_share and kind != "plan" and draw.chance(valid_share):
                    if kind in ("simulate", "agents"):
                        valid_scenario_case(draw, case, agents=kind == "agents")
                    else:
                        valid_study_case(draw, case, grid=kind == "grid")
                elif kind == "plan":
                    plan_case(draw, case, keys)
                elif kind in ("simulate", "agents"):
                    scenario_case(draw, case, keys, agents=kind == "agents")
                else:
                    study_case(draw, case, keys, grid=kind == "grid")
        except StopTest:
            continue
        return case
    raise RuntimeError(f"case {seed}:{kind}:{index} could not be drawn")


# ---------------------------------------------------------------------------- running


@dataclass
class Result:
    code: int
    out: str
    err: str
    seconds: float
    timed_out: bool
    survivors: list[int]
    peak_rss: int


def _session_pids(sid: int) -> dict[int, int]:
    """PID -> resident bytes of the live (not zombie) processes of session ``sid``."""
    found: dict[int, int] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        rest = stat[stat.rfind(")") + 2:].split()
        if rest[0] == "Z" or int(rest[3]) != sid:
            continue
        found[int(d)] = int(rest[21]) * resource.getpagesize()
    return found


def run_case(case: Case, python: str, timeout: float, workdir: Path) -> Result:
    for name, data in case.files.items():
        if name == "@full":
            (workdir / "out").mkdir()
            (workdir / "out" / "episode.png").symlink_to("/dev/full")
            continue
        (workdir / name).write_bytes(data)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), **case.env}
    env.pop("SENSORPLAN_DEBUG", None)

    def limits() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (8 << 30, 8 << 30))
        # Ctrl-C as in a terminal, even where this driver runs as a script's background job
        # (started with Ctrl-C ignored, which a command inherits and keeps).
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    start = time.monotonic()
    stdout: Any = subprocess.PIPE
    if case.closed_stdout:        # a reader that is gone: writes fail with EPIPE
        read_end, stdout = os.pipe()
        os.close(read_end)
    proc = subprocess.Popen(["nice", "-n", "15", python, "-m", "sensorplan", *case.args],
                            cwd=workdir, env=env, stdin=subprocess.DEVNULL,
                            stdout=stdout, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=limits)
    if case.closed_stdout:
        os.close(stdout)
    seen: set[int] = set()
    peak = 0
    stop = threading.Event()

    def watch() -> None:
        nonlocal peak
        while not stop.is_set():
            pids = _session_pids(proc.pid)
            seen.update(pids)
            peak = max(peak, sum(pids.values()))
            stop.wait(0.2)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    if case.interrupt_after is not None:
        timer = threading.Timer(case.interrupt_after, _interrupt, (proc,))
        timer.start()
    timed_out = False
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        _kill_session(proc.pid)
        out, err = proc.communicate()
    finally:
        if case.interrupt_after is not None:
            timer.cancel()
    seconds = time.monotonic() - start
    stop.set()
    watcher.join()
    time.sleep(0.3)
    survivors = sorted(set(_session_pids(proc.pid)) & seen)
    if survivors:
        time.sleep(1.5)
        survivors = sorted(set(_session_pids(proc.pid)) & seen)
        for pid in survivors:                  # the processes this case started
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
    return Result(proc.returncode, (out or b"").decode("utf-8", "replace"),
                  err.decode("utf-8", "replace"), seconds, timed_out, survivors, peak)


def _interrupt(proc: subprocess.Popen[bytes]) -> None:
    try:
        os.killpg(proc.pid, signal.SIGINT)      # as a terminal's Ctrl-C: the whole group
    except OSError:
        pass


def _kill_session(sid: int) -> None:
    for pid in _session_pids(sid):
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def shown(field_: str) -> str:
    """A field as an error line shows it (control characters escaped, long ones cut)."""
    from sensorplan.errors import error_line

    return error_line(field_, "m")[len("error: "):-len(": m")]


def verdict(case: Case, r: Result, workdir: Path) -> tuple[str, str]:
    """("clean" | "ok" | "defect" | "suspect", why)."""
    if r.timed_out:
        return "defect", "no answer within the time limit (a hang)"
    if r.survivors:
        return "defect", f"processes left behind: {r.survivors}"
    if r.peak_rss > 2 << 30:
        return "defect", f"{r.peak_rss / 2**30:.1f} GB resident"
    code = r.code          # killed by a signal: negative, never allowed
    outcome = fz.Outcome(code, r.out, r.err)
    if case.command in ("study", "grid") and code == 0:
        outcome = fz.Outcome(0, "", r.err)          # stdout: the summary lines
    if case.command in ("simulate", "agents") and code == 0:
        outcome = fz.Outcome(0, "", r.err)          # stdout: the tables
    try:
        fz.check_outcome(outcome, case.command, ("note: ",),
                         interrupted=case.interrupt_after is not None,
                         closed_stdout=case.closed_stdout)
    except AssertionError as exc:
        return "defect", f"contract: {exc}"
    except (ValueError, json.JSONDecodeError) as exc:
        return "defect", f"contract: {exc}"
    if code == 0 and case.command != "plan" and not case.closed_stdout:
        for f in case.success_files:
            if not (workdir / f).exists():
                return "defect", f"exit 0 without {f}"
        if "nan" in r.out.lower().split() or "inf" in r.out.lower().split():
            return "suspect", "a non-finite number in the summary"
    if code in (130, 141, 143):
        return "ok", f"exit {code}"
    e = case.expect
    if e.refuse and code == 0:
        return "suspect", "accepted: " + "; ".join(e.why)
    if code == 2 and e.refuse and e.fields:
        line = r.err.strip()
        # The field, and for a file inside another (a study's scenario file) the fields
        # after it: "error: scenario.file: scenario.toml: targets[0].kind: ...".
        named = line[len("error: "):].split(": ")[:4]
        files = {f.split(":", 1)[1] for f in e.fields if f.startswith("FILE:")}
        files |= {str(workdir / f) for f in files}
        wanted = {shown(f) for f in e.fields if not f.startswith("FILE:")} | (
            {"FILE"} if files else set())
        if not any(field_matches(n, w, files) for n in named for w in wanted):
            return "suspect", f"names {named[0]!r}, expected one of {sorted(e.fields)}"
    return ("clean" if code == 2 else "ok"), ""


# ------------------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", choices=KINDS, required=True)
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--cases", type=int, required=True)
    parser.add_argument("--start", type=int, default=0, help="first case index (to resume)")
    parser.add_argument("--out", type=Path, required=True,
                        help="directory for the case log and the failing cases")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds per case")
    parser.add_argument("--python", default=sys.executable)
    parser.add_argument("--only", type=int, nargs="*", help="run these case indices only")
    parser.add_argument("--valid-share", type=float, default=0.0,
                        help="share of simulate, agents, study and grid cases that are valid "
                             "runs (default 0: every case mutated)")
    args = parser.parse_args(argv)

    out = args.out / f"{args.kind}-{args.seed}"
    out.mkdir(parents=True, exist_ok=True)
    keys = known_keys()
    counts: dict[str, int] = {}
    indices = args.only if args.only else range(args.start, args.start + args.cases)
    log = gzip.open(out / "cases.jsonl.gz", "at")
    try:
        for i in indices:
            case = build(args.kind, args.seed, i, keys, args.valid_share)
            workdir = Path(tempfile.mkdtemp(prefix="sensorplan-fuzz-"))
            r = run_case(case, args.python, args.timeout, workdir)
            v, why = verdict(case, r, workdir)
            counts[v] = counts.get(v, 0) + 1
            record = {"kind": args.kind, "seed": args.seed, "index": i, "args": case.args,
                      "done": case.done, "refuse": case.expect.refuse,
                      "fields": sorted(case.expect.fields) if case.expect.fields else None,
                      "code": r.code, "seconds": round(r.seconds, 2), "verdict": v,
                      "why": why, "stderr": r.err[:500] if v in ("defect", "suspect")
                      else r.err.strip().splitlines()[-1][:300] if r.err.strip() else "",
                      "files": {k: v_.decode("utf-8", "backslashreplace")[:200_000]
                                for k, v_ in case.files.items()}}
            log.write(json.dumps(record) + "\n")
            log.flush()
            if v in ("defect", "suspect"):
                keep = out / f"{v}-{i:05d}"
                shutil.rmtree(keep, ignore_errors=True)
                keep.mkdir()
                for name, data in case.files.items():
                    if not name.startswith("@"):
                        (keep / name).write_bytes(data)
                (keep / "case.json").write_text(json.dumps(
                    {**{k: record[k] for k in ("kind", "seed", "index", "args", "done",
                                               "refuse", "fields", "code", "why")},
                     "stdout": r.out[:5000], "stderr": r.err[:20000],
                     "interrupt_after": case.interrupt_after,
                     "closed_stdout": case.closed_stdout}, indent=1))
            print(f"{args.kind} {i}: {v} exit {r.code} {r.seconds:.1f}s "
                  f"{why[:150]!r}" if v in ("defect", "suspect") else
                  f"{args.kind} {i}: {v} exit {r.code} {r.seconds:.1f}s", flush=True)
            shutil.rmtree(workdir, ignore_errors=True)
    finally:
        log.close()
    total = sum(counts.values())
    print(f"{args.kind} seed {args.seed}: {total} cases: "
          + ", ".join(f"{counts[k]} {k}" for k in sorted(counts)), flush=True)
    (out / f"summary-{args.start}.json").write_text(json.dumps(
        {"kind": args.kind, "seed": args.seed, "cases": total, "counts": counts}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
