"""Mutated input documents for the fuzz tests: valid documents, mutations, writers, checks.

A case is a valid document (a ``plan`` JSON object, a scenario or a study TOML table)
changed by one to three hypothesis-drawn mutations: a value replaced by another type, a
non-finite, extreme or huge number, an over-long integer literal, a huge or hostile string,
a list of the wrong shape, deep nesting; a key deleted, added or repeated; angles in
degrees; then, sometimes, the text cut short. :func:`check_outcome` states the contract
every case must meet.
"""

from __future__ import annotations

import copy
import json
import math
import re
from dataclasses import dataclass, field
from typing import Any

from hypothesis import strategies as st

# ------------------------------------------------------------------------ documents

PLAN_DOC: dict[str, Any] = {
    "dt": 1.0, "steps_per_epoch": 1, "horizon": 2,
    "map": {"width": 600, "height": 600},
    "process_noise": 0.05, "visibility": "probabilistic", "objective": "terminal",
    "targets": [{"mean": [300, 200, 4, 1],
                 "cov": [[400, 0, 0, 0], [0, 400, 0, 0], [0, 0, 4, 0], [0, 0, 0, 4]]},
                {"mean": [420, 380, -2, 3],
                 "cov": [[900, 0, 0, 0], [0, 900, 0, 0], [0, 0, 9, 0], [0, 0, 0, 9]]}],
    "sensors": [{"position": [100, 100], "altitude": 500, "heading": 0.0,
                 "moves": [20, 40], "max_turn": 0.785398, "fov_half_angle": 0.523599,
                 "min_ground_range": 250, "max_ground_range": 450, "depression": 0.698132,
                 "snr_ref_db": 15, "range_ref": 600, "beamwidth": 0.0523599,
                 "monopulse_slope": 1.6, "range_resolution": 30},
                {"position": [500, 300], "heading": 3.0, "altitude": 490}],
    "planner": {"name": "pg", "alpha": 0.3, "beta": 0.95, "max_inner": 20, "max_outer": 5,
                "seed": 0},
}

SCENARIO_DOC: dict[str, Any] = {
    "dt": 1.0, "process_noise": 0.05,
    "map": {"width": 600.0, "height": 600.0},
    "initial": {"target_box": [100.0, 500.0], "speed_range": [3.0, 6.0],
                "sensor_box": [50.0, 550.0],
                "cov": [[400.0, 0.0, 0.0, 0.0], [0.0, 400.0, 0.0, 0.0],
                        [0.0, 0.0, 4.0, 0.0], [0.0, 0.0, 0.0, 4.0]]},
    "planning": {"planner": "pg", "horizon": 1, "steps_per_epoch": 1,
                 "planner_params": {"max_inner": 10}},
    "tracker": {"miss_update": "negative", "model": "imm"},
    "run": {"steps": 3, "seed": 1},
    "targets": [{"kind": "cv", "position": [300.0, 250.0], "speed": 4.0, "heading": 0.5},
                {"kind": "dubins", "turn_hold": 10.0, "max_turn_rate": 0.1}],
    "sensors": [{"altitude": 490.0, "position": [100.0, 100.0], "heading": 0.78,
                 "moves": [20.0, 40.0], "fov_half_angle": 0.52},
                {"altitude": 510.0, "max_turn": 0.78, "depression": 0.7}],
}

STUDY_DOC: dict[str, Any] = {
    "description": "fuzz", "runs": 1, "steps": 2, "seed": 3,
    "scenario": {"preset": "paper"},
    "defaults": {"steps_per_epoch": 1, "tracker": {"miss_update": "none"}},
    "methods": [{"name": "rnd", "planner": "random"},
                {"name": "pg", "planner": "pg", "horizon": 1,
                 "planner_params": {"max_inner": 10, "max_outer": 3}}],
}

# Documents that also use the keys added since (births and deaths, scripted truths, the
# tracker's kind, headings in degrees, detection and clutter, buildings, the decentralized
# planners' settings), each valid as it stands.

PLAN_DOC_NEW: dict[str, Any] = {
    **PLAN_DOC, "planning_detection": "aware",
    "sensors": [{**PLAN_DOC["sensors"][0], "detection": "swerling1",
                 "false_alarm_probability": 1e-4, "clutter_rate": 0.5},
                {"position": [500, 300], "heading_deg": 170, "altitude": 490,
                 "fov_half_angle_deg": 30, "max_turn_deg": 45}],
    "buildings": [{"box": [250, 250, 300, 300], "height": 60},
                  {"box": [350, 100, 400, 150], "height": 30}],
    "planner": {"name": "pg", "max_inner": 10, "max_outer": 3, "seed": 2},
}

SCENARIO_DOC_NEW: dict[str, Any] = {
    "dt": 1.0, "process_noise": 0.05,
    "births": "none", "birth_rate": 0.0, "survival_probability": 1.0, "initial_targets": 2,
    "map": {"width": 600.0, "height": 600.0},
    "initial": {"target_box": [100.0, 500.0], "speed_range": [3.0, 6.0]},
    "planning": {"planner": "pg", "horizon": 1, "steps_per_epoch": 1,
                 "planning_detection": "aware", "planning_occlusion": "aware",
                 "planner_params": {"max_inner": 10}},
    "tracker": {"kind": "known", "miss_update": "negative", "model": "imm",
                "association": "pda", "gate": True, "reacquire": False},
    "run": {"steps": 3, "seed": 1},
    "targets": [{"kind": "cv", "position": [300.0, 250.0], "speed": 4.0, "heading_deg": 30.0},
                {"kind": "dubins", "turn_hold": 10.0, "max_turn_rate_deg": 6.0}],
    "sensors": [{"altitude": 490.0, "position": [100.0, 100.0], "heading_deg": 45.0,
                 "detection": "swerling1", "false_alarm_probability": 1e-4,
                 "clutter_rate": 0.5},
                {"altitude": 510.0, "max_turn": 0.78, "depression_deg": 40.0}],
    "buildings": [{"box": [400.0, 400.0, 450.0, 450.0], "height": 40.0}],
}

#: A scenario whose targets are born and die (refused by the tracker of known targets, the
#: only kind so far: the error must name what to change).
SCENARIO_DOC_BIRTHS: dict[str, Any] = {
    **SCENARIO_DOC_NEW, "births": "edges", "birth_rate": 0.2, "survival_probability": 0.98,
    "initial_targets": 1,
}

#: A published benchmark's scripted truth: its map and dt, no [[targets]].
SCENARIO_DOC_SCRIPTED: dict[str, Any] = {
    "scripted": "williams15", "dt": 1.0, "map": {"width": 300.0, "height": 300.0},
    "run": {"steps": 3, "seed": 2}, "tracker": {"kind": "known"},
    "sensors": [{"altitude": 300.0, "heading_deg": 10.0, "min_ground_range": 50.0,
                 "max_ground_range": 250.0}],
}

#: A scenario for ``sensorplan agents``: a decentralized planner and its link settings.
AGENTS_DOC: dict[str, Any] = {
    **SCENARIO_DOC_NEW,
    "planning": {"planner": "dec-jsfp", "horizon": 1,
                 "planner_params": {"rounds": 30, "p_loss": 0.1, "delay": 1,
                                    "comm_range": 400.0, "mode": "jsfp"}},
}

STUDY_DOC_NEW: dict[str, Any] = {
    "description": "fuzz", "runs": 1, "steps": 2, "seed": 3,
    "scenario": {"preset": "radar"},
    "defaults": {"steps_per_epoch": 1, "planning_detection": "aware",
                 "tracker": {"kind": "known", "miss_update": "none", "model": "cv"}},
    "methods": [{"name": "rnd", "planner": "random"},
                {"name": "seq", "planner": "dec-sequential",
                 "planner_params": {"p_loss": 0.1, "comm_range": 300.0},
                 "tracker": {"association": "nearest"}}],
}

GRID_DOC: dict[str, Any] = {
    "description": "fuzz grid", "runs": 1, "steps": 2, "seed": 5, "design": "star",
    "scenario": {"preset": "radar"},
    "defaults": {"steps_per_epoch": 1, "tracker": {"kind": "known"}},
    "axes": [{"feature": "clutter_rate", "values": [0.0, 1.0], "base": 0.0},
             {"feature": "setting", "key": "planner_params.p_loss", "values": [0.0, 0.2],
              "base": 0.0}],
    "methods": [{"name": "rnd", "planner": "random"},
                {"name": "dj", "planner": "dec-jsfp", "planner_params": {"rounds": 20}}],
    "comparisons": [{"method": "dj", "reference": "rnd", "label": "dj vs rnd"}],
}

#: Other axes a grid document may have instead (values kept few and small).
GRID_AXES: list[dict[str, Any]] = [
    {"feature": "sensor_speed", "values": [0.5, 1.0], "base": 1.0},
    {"feature": "min_ground_range", "values": [150.0, 250.0], "base": 250.0},
    {"feature": "town", "values": [0.0, 30.0], "base": 0.0},
    {"feature": "snr_ref_db", "values": [15.0, float("inf")], "base": 15.0},
    {"feature": "clutter_rate", "values": [0.0, 2.0], "base": 0.0},
    {"feature": "setting", "key": "horizon", "values": [1, 2], "base": 1},
    {"feature": "setting", "key": "tracker.miss_update", "values": ["negative", "none"],
     "base": "negative"},
    {"feature": "setting", "key": "tracker.kind", "values": ["known"], "base": "known"},
    {"feature": "setting", "key": "planner_params.rounds", "values": [5, 20], "base": 20},
]

#: Keys whose value sets how much work a valid document asks for: their mutations draw
#: values that are refused or small, never a valid but hours-long request (the size
#: limits themselves are tested on their own).
SIZE_KEYS = {"steps", "runs", "horizon", "steps_per_epoch", "max_inner", "max_outer",
             "max_plans", "rounds"}

# ------------------------------------------------------------------- special values


@dataclass(frozen=True)
class Raw:
    """Text written verbatim into the document (deep nesting, over-long integers)."""

    text: str


class DupDict(dict):  # type: ignore[type-arg]
    """A table written with one key twice (JSON: both pairs; TOML: both lines)."""

    dup: str = ""
    dup_value: Any = None


def deep(depth: int, leaf: str = "1") -> Raw:
    return Raw("[" * depth + leaf + "]" * depth)


HOSTILE_STRINGS = [
    "", " ", "x" * 100_000, "\x1b[31mred\x07", "a\nb", "\t", "\u202e", "é", "\ud800",
    "\udfff", "pg\x00", "../../etc/passwd", "{}", "[]", "null", "NaN", "1e999", "paper ",
    "Paper", "module:Class", "os:system", "sensorplan.planners:nothing",
]
EXTREME_NUMBERS = [
    0, -1, 1, 0.0, -0.0, 1e-300, -1e-300, 5e-324, 1e300, -1e300, 1.7976931348623157e308,
    float("nan"), float("inf"), float("-inf"), 1e16, 2**53 + 1, 2**63, -(2**63), 2**64,
    10**400, 0.5, 3.0, 30, 45, 90, 180, 360, 1e6, 1e7, 1e-6, 3600, 3601, 1e14, 1e15,
]


def huge_int(digits: int) -> Raw:
    return Raw("1" + "0" * (digits - 1))


def values() -> st.SearchStrategy[Any]:
    """A replacement value of any kind."""
    return st.one_of(
        st.sampled_from(EXTREME_NUMBERS),
        st.sampled_from(HOSTILE_STRINGS),
        st.sampled_from([None, True, False, [], {}, [1], [[1, 2], [3, 4]], {"a": 1}]),
        st.integers(-10**6, 10**6),
        st.floats(allow_nan=True, allow_infinity=True),
        st.text(max_size=20),
        st.lists(st.floats(-1e6, 1e6), max_size=6),
        st.integers(4290, 4400).map(huge_int),
        st.integers(30, 3000).map(deep),
    )


def size_values() -> st.SearchStrategy[Any]:
    return st.sampled_from([0, -1, 1, 2, 3, 10**20, 2**63, 10**6, 1001, 100_001, 2.0, "3",
                            None, True, [2], float("nan"), huge_int(4301), deep(200)])


# ------------------------------------------------------------------------ mutations


def paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path to a value (tables, lists and leaves) below the root."""
    out: list[tuple[Any, ...]] = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) \
        if isinstance(doc, list) else ()
    for k, v in items:
        out.append(prefix + (k,))
        out += paths(v, prefix + (k,))
    return out


def _parent(doc: Any, path: tuple[Any, ...]) -> Any:
    for p in path[:-1]:
        doc = doc[p]
    return doc


#: The keys added most recently (targets born and dying, scripted truths, the tracker's
#: kind, headings in degrees, the radar's detection keys, buildings): a focused mutation
#: (``mutate(..., focus=NEW_KEYS)``) picks a path through one of them two times in three.
NEW_KEYS = ("heading_deg", "births", "birth_rate", "survival_probability", "initial_targets",
            "scripted", "kind", "tracker", "detection", "false_alarm_probability",
            "clutter_rate", "buildings", "planning_detection", "planning_occlusion")


@st.composite
def mutate(draw: st.DrawFn, base: dict[str, Any], json_doc: bool,
           focus: tuple[str, ...] = (), log: list[dict[str, Any]] | None = None
           ) -> tuple[Any, list[str]]:
    """A mutated copy of ``base`` and the list of what was done (for failure reports).

    ``focus``: key names that two mutations in three aim at (a path through one of them),
    and that ``add`` also draws. ``log``: receives one record per mutation (``kind``,
    ``path``, ``old``, ``new``, ...), for an oracle of what the command must say. Without
    either, the draws are those of earlier versions (the derandomized suite keeps its
    cases).
    """
    doc = copy.deepcopy(base)
    done: list[str] = []

    def record(**what: Any) -> None:
        if log is not None:
            log.append(what)

    for _ in range(draw(st.integers(1, 3))):
        all_paths = paths(doc)
        kinds = ["replace"] * 6 + ["delete", "delete", "add", "add", "duplicate", "shape",
                                   "shape", "degrees", "degrees"] + (["root"] if json_doc else [])
        kind = draw(st.sampled_from(kinds))
        if kind == "root":
            doc = draw(st.sampled_from([[], "x", 1, None, [doc], deep(5000, "{}")]))
            done.append(f"root -> {_short(doc)}")
            record(kind="root", path=(), new=doc)
            break
        if not all_paths:
            break
        if focus and draw(st.integers(0, 2)) < 2:
            aimed = [p for p in all_paths if any(str(x) in focus for x in p)]
            path = draw(st.sampled_from(aimed or all_paths))
        else:
            path = draw(st.sampled_from(all_paths))
        parent = _parent(doc, path)
        key = path[-1]
        if kind == "replace":
            new = draw(size_values() if key in SIZE_KEYS else values())
            record(kind="replace", path=path, old=parent[key], new=new)
            parent[key] = new
            done.append(f"{_fmt(path)} = {_short(new)}")
        elif kind == "delete":
            record(kind="delete", path=path, old=parent[key])
            if isinstance(parent, dict):
                del parent[key]
            else:
                parent.pop(key)
            done.append(f"del {_fmt(path)}")
        elif kind == "add":
            table = parent if isinstance(parent, dict) else doc
            if not isinstance(table, dict):
                continue
            names = st.sampled_from(["fov_half_angle_deg", "max_turn_deg", "depression_deg",
                                     "beamwidth_deg", "max_turn_rate_deg", "horizn",
                                     "\ud800", "a\x1b[31mb\x07", "x" * 5000, ""])
            if focus:
                names = st.one_of(names, st.sampled_from(focus))
            name = draw(st.one_of(names, st.text(min_size=1, max_size=12)))
            if not json_doc and any("\ud800" <= c <= "\udfff" for c in name):
                name = "surrogate"
            value = draw(values())
            where = path[:-1] if table is parent else ()
            record(kind="add", path=where + (name,), new=value, existed=name in table)
            table[name] = value
            done.append(f"add {_fmt(path[:-1] + (name,))}")
        elif kind == "duplicate":
            if not isinstance(parent, dict):
                continue
            dup = DupDict(parent)
            dup.dup, dup.dup_value = key, draw(values())
            grand = _parent(doc, path[:-1]) if len(path) > 1 else None
            if grand is None:
                doc = dup
            else:
                grand[path[-2]] = dup
            done.append(f"duplicate {_fmt(path)}")
            record(kind="duplicate", path=path)
        elif kind == "shape":
            v = parent[key]
            if isinstance(v, list):
                choice = draw(st.sampled_from(["short", "long", "wrap", "empty"]))
                parent[key] = {"short": v[:-1], "long": v + v[:1], "wrap": [v],
                               "empty": []}[choice]
                done.append(f"{_fmt(path)} {choice}")
            else:
                choice = "listed"
                parent[key] = [v, v]
                done.append(f"{_fmt(path)} listed")
            record(kind="shape", path=path, old=v, choice=choice)
        elif kind == "degrees":
            if isinstance(parent, dict) and isinstance(parent.get(key), (int, float)) \
                    and not isinstance(parent.get(key), bool):
                angle = draw(st.sampled_from([30, 45, 40, 3, 90, 180, 200, -10]))
                both = draw(st.booleans())
                name = draw(st.sampled_from(["fov_half_angle", "max_turn", "depression",
                                             "beamwidth", "max_turn_rate"]))
                record(kind="degrees", path=path[:-1] + (name,), new=angle, both=both,
                       deg_existed=name + "_deg" in parent)
                if both:
                    parent[name] = 0.5
                    parent[name + "_deg"] = angle
                else:
                    parent[name] = angle
                done.append(f"{_fmt(path[:-1])}.{name}{'(+_deg)' if both else ''} = {angle}")
    return doc, done


def _fmt(path: tuple[Any, ...]) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{_short(p)}" for p in path)


def _short(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


# --------------------------------------------------------------------------- writers


def to_json(v: Any) -> str:
    """JSON text; NaN and infinities as Python writes them (``NaN``, ``Infinity``)."""
    if isinstance(v, Raw):
        return v.text
    if isinstance(v, dict):
        pairs = [f"{json.dumps(str(k))}: {to_json(x)}" for k, x in v.items()]
        if isinstance(v, DupDict):
            pairs.append(f"{json.dumps(v.dup)}: {to_json(v.dup_value)}")
        return "{" + ", ".join(pairs) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(to_json(x) for x in v) + "]"
    return json.dumps(v)


def _toml_key(k: Any) -> str:
    k = str(k)
    if k and all(c.isalnum() or c in "_-" for c in k) and k.isascii():
        return k
    return _toml_str(k)


def _toml_str(s: str) -> str:
    out = []
    for c in s:
        if c in '"\\':
            out.append("\\" + c)
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        elif "\ud800" <= c <= "\udfff":
            out.append(f"\\u{ord(c):04x}")        # tomllib refuses it: an invalid file
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def toml_value(v: Any) -> str:
    if isinstance(v, Raw):
        return v.text
    if v is None:
        return '""'                       # TOML has no null: an empty string instead
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, dict):
        pairs = [f"{_toml_key(k)} = {toml_value(x)}" for k, x in v.items()]
        if isinstance(v, DupDict):
            pairs.append(f"{_toml_key(v.dup)} = {toml_value(v.dup_value)}")
        return "{" + ", ".join(pairs) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return _toml_str(str(v))


def to_toml(doc: Any) -> str:
    """TOML text: top-level scalars, then tables and arrays of tables; anything deeper
    inline. A root that is not a table becomes a key the models refuse."""
    if not isinstance(doc, dict):
        return f"root = {toml_value(doc)}\n"
    lines = []
    items = list(doc.items())
    if isinstance(doc, DupDict):
        items.append((doc.dup, doc.dup_value))
    for k, v in items:
        if not isinstance(v, dict) and not (isinstance(v, list) and v
                                            and all(isinstance(x, dict) for x in v)):
            lines.append(f"{_toml_key(k)} = {toml_value(v)}")
    for k, v in items:
        if isinstance(v, dict):
            lines.append(f"[{_toml_key(k)}]")
            sub = list(v.items()) + ([(v.dup, v.dup_value)] if isinstance(v, DupDict) else [])
            lines += [f"{_toml_key(a)} = {toml_value(b)}" for a, b in sub]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                lines.append(f"[[{_toml_key(k)}]]")
                sub = list(x.items()) + ([(x.dup, x.dup_value)] if isinstance(x, DupDict)
                                         else [])
                lines += [f"{_toml_key(a)} = {toml_value(b)}" for a, b in sub]
    return "\n".join(lines) + "\n"


@st.composite
def document(draw: st.DrawFn, base: dict[str, Any], json_doc: bool) -> tuple[str, list[str]]:
    """The text of a mutated document, perhaps cut short, and what was done to it."""
    doc, done = draw(mutate(base, json_doc))
    text = to_json(doc) if json_doc else to_toml(doc)
    if draw(st.integers(0, 14)) == 0:
        cut = draw(st.integers(1, 99)) * len(text) // 100
        text = text[:cut]
        done.append(f"cut at {cut}")
    return text, done


TEXT_DAMAGE = ("cut", "nul", "xff", "quote", "bracket", "bom", "crlf", "repeat", "utf16",
               "empty")


@st.composite
def damaged(draw: st.DrawFn, text: str) -> tuple[bytes, str]:
    """The bytes of ``text`` after one text-level change, and its name: cut short, a NUL,
    0xFF, a quote or a bracket inserted, a BOM, CRLF line ends, a line repeated, UTF-16,
    or emptied."""
    how = draw(st.sampled_from(TEXT_DAMAGE))
    data = text.encode("utf-8", "surrogatepass")
    at = draw(st.integers(0, max(0, len(data) - 1)))
    if how == "cut":
        data = data[:at]
    elif how in ("nul", "xff", "quote", "bracket"):
        data = data[:at] + {"nul": b"\x00", "xff": b"\xff", "quote": b'"',
                            "bracket": b"["}[how] + data[at:]
    elif how == "bom":
        data = b"\xef\xbb\xbf" + data
    elif how == "crlf":
        data = data.replace(b"\n", b"\r\n")
    elif how == "repeat":
        lines = data.split(b"\n")
        k = draw(st.integers(0, max(0, len(lines) - 1)))
        data = b"\n".join(lines[:k + 1] + lines[k:])
    elif how == "utf16":
        data = text.encode("utf-16", "surrogatepass")
    else:
        data = b""
    return data, f"text {how}" + (f" at {at}" if how in ("cut", "nul", "xff", "quote",
                                                          "bracket") else "")


# ------------------------------------------------------------------------- contract


@dataclass
class Outcome:
    code: int
    out: str
    err: str
    notes: list[str] = field(default_factory=list)


def _finite_numbers(v: Any) -> bool:
    if isinstance(v, float):
        return math.isfinite(v)
    if isinstance(v, dict):
        return all(_finite_numbers(x) for x in v.values())
    if isinstance(v, list):
        return all(_finite_numbers(x) for x in v)
    return True


def _no_constant(name: str) -> Any:
    raise ValueError(f"non-finite number {name} in the output")


#: A plain progress line (sensorplan.cli.console.PlainProgress): ``LABEL: 3/6 (run,
#: method) pairs done, 6 s elapsed, ETA 5 s``.
PROGRESS = re.compile(r"^.*: \d+/\d+( [^,]*)? done( \(\d+ already done before\))?, "
                      r"\d+ s elapsed(, ETA \d+ s)?$")


def check_outcome(o: Outcome, command: str, progress_prefixes: tuple[str, ...] = (), *,
                  interrupted: bool = False, closed_stdout: bool = False) -> None:
    """The contract: exit 2 with exactly one stderr line ``error: <field>: <message>``
    naming a field, nothing on stdout, no traceback; or success (exit 0) with a valid
    result and nothing on stderr but progress lines.

    ``interrupted``: the case sent a Ctrl-C, so 130 (or 143) with one line besides progress
    is allowed too. ``closed_stdout``: the reader closed standard output first, so 141 with
    nothing but progress on stderr is allowed (what a shell reports for ``| head -1``),
    and a success has no output to check."""
    where = f"{command}: exit {o.code}\nstdout: {o.out[:300]!r}\nstderr: {o.err[:600]!r}"
    assert "Traceback" not in o.err, where
    assert "Warning" not in o.err, where

    def progress(line: str) -> bool:
        return line.startswith(progress_prefixes) or bool(PROGRESS.match(line))

    if interrupted and o.code in (130, 143):
        said = [line for line in o.err.splitlines() if not progress(line)]
        assert len(said) == 1, where
        assert said[0].startswith(("error: interrupted", "error: terminated",
                                   "interrupted")), where
        return
    if closed_stdout and o.code == 141:
        assert all(progress(line) for line in o.err.splitlines()), where
        return
    if o.code == 2:
        lines = o.err.splitlines()
        assert len(lines) == 1, where
        assert lines[0].startswith("error: "), where
        field_, sep, message = lines[0][len("error: "):].partition(": ")
        assert sep and field_.strip() and message.strip(), where
        assert field_ not in ("internal error", "usage"), where
        assert o.out == "", where
        assert len(lines[0]) < 700, where
        assert not any(ord(c) < 0x20 or 0x7F <= ord(c) < 0xA0 or 0xD800 <= ord(c) < 0xE000
                       for c in lines[0]), where              # no raw control characters
        return
    assert o.code == 0, where
    for line in o.err.splitlines():
        assert progress(line), where
    if command == "plan" and not closed_stdout:
        result = json.loads(o.out, parse_constant=_no_constant)
        assert _finite_numbers(result), where
        assert set(result) >= {"planner", "plan", "potential", "information", "seconds"}, where
        assert math.isclose(sum(result["information"]), result["potential"], rel_tol=1e-9,
                            abs_tol=1e-9), where
        # Phi >= 0 up to rounding (a plan that gains nothing can come out at -1e-13).
        assert result["potential"] >= -1e-8 * max(1.0, abs(result["potential"])), where


# ------------------------------------------------------- valid but extreme documents


def in_range(kind: str, draw: st.DrawFn) -> float:
    """A value inside ``RANGES[kind]``: often a bound, else log-uniform between them."""
    from sensorplan.limits import RANGES

    r = RANGES[kind]
    hi = r.hi if r.hi is not None else 1e6
    lo = r.lo if r.lo is not None else 0.0
    if r.magnitude:
        lo = 0.0
    eps = 1e-12 * max(abs(hi), 1.0)
    lo_in = lo + (eps if r.lo_open or lo == 0.0 else 0.0)
    hi_in = hi - (eps if r.hi_open else 0.0)
    choice = draw(st.integers(0, 4))
    if choice == 0:
        v = lo_in
    elif choice == 1:
        v = hi_in
    else:
        a, b = math.log10(max(lo_in, 1e-12)), math.log10(max(hi_in, 1e-12))
        v = 10.0 ** draw(st.floats(min(a, b), max(a, b)))
        v = min(max(v, lo_in), hi_in)
    if r.magnitude and draw(st.booleans()):
        v = -v
    return v


@st.composite
def extreme_plan(draw: st.DrawFn) -> dict[str, Any]:
    """A valid decision with every number drawn from its documented range (bounds often)."""
    W = in_range("length", draw) if draw(st.booleans()) else 600.0
    H = in_range("length", draw) if draw(st.booleans()) else 600.0
    M = draw(st.integers(1, 3))
    N = draw(st.integers(1, 2))

    def cov() -> list[list[float]]:
        base = draw(st.floats(-9, 8))
        d = [10.0 ** min(14.0 if i < 2 else 8.0, base + draw(st.floats(0, 11)))
             for i in range(4)]
        c = draw(st.floats(-0.99, 0.99))
        P = [[0.0] * 4 for _ in range(4)]
        for i in range(4):
            P[i][i] = d[i]
        P[0][1] = P[1][0] = c * math.sqrt(d[0] * d[1])
        return P

    def sensor() -> dict[str, Any]:
        return {"position": [draw(st.floats(0, W)), draw(st.floats(0, H))],
                **draw(extreme_radar())}

    return {
        "dt": in_range("dt", draw), "steps_per_epoch": draw(st.integers(1, 4)),
        "horizon": draw(st.integers(1, 4)), "map": {"width": W, "height": H},
        "process_noise": in_range("process_noise", draw),
        "visibility": draw(st.sampled_from(["probabilistic", "mean"])),
        "objective": draw(st.sampled_from(["terminal", "cumulative"])),
        "planning_detection": draw(st.sampled_from(["aware", "ignore"])),
        "targets": [{"mean": [in_range("coordinate", draw), in_range("coordinate", draw),
                              in_range("velocity", draw), in_range("velocity", draw)],
                     "cov": cov()} for _ in range(M)],
        "sensors": [sensor() for _ in range(N)],
        "planner": {"name": draw(st.sampled_from(["pg", "random", "sequential-greedy",
                                                  "pg-refine", "brute-force"])),
                    "seed": draw(st.integers(0, 10))},
    }


@st.composite
def extreme_radar(draw: st.DrawFn) -> dict[str, Any]:
    """Every radar key of a sensor, drawn from its documented range."""
    g_lo, g_hi = sorted([in_range("ground_range", draw), in_range("ground_range", draw)])
    return {"heading": in_range("heading", draw), "altitude": in_range("altitude", draw),
            "moves": [in_range("length", draw) if draw(st.booleans())
                      else draw(st.sampled_from([20.0, 40.0, 7.5]))
                      for _ in range(draw(st.integers(1, 3)))],
            "max_turn": in_range("max_turn", draw),
            "fov_half_angle": in_range("fov_half_angle", draw),
            "min_ground_range": max(g_lo, 1e-9), "max_ground_range": max(g_hi, 1.0),
            "depression": in_range("depression", draw),
            "snr_ref_db": in_range("snr_ref_db", draw),
            "range_ref": in_range("range_ref", draw),
            "beamwidth": in_range("beamwidth", draw),
            "monopulse_slope": in_range("monopulse_slope", draw),
            "range_resolution": in_range("range_resolution", draw),
            "detection": draw(st.sampled_from(["ideal", "swerling1"])),
            "false_alarm_probability": 10.0 ** draw(st.floats(-300, -1e-9)),
            "clutter_rate": in_range("clutter_rate", draw)}


@st.composite
def extreme_scenario(draw: st.DrawFn) -> dict[str, Any]:
    """A valid scenario file with every number drawn from its documented range."""
    W = in_range("length", draw) if draw(st.booleans()) else 600.0
    H = in_range("length", draw) if draw(st.booleans()) else 600.0
    base = draw(st.floats(-9, 8))
    cov = [[0.0] * 4 for _ in range(4)]
    for i in range(4):
        cov[i][i] = 10.0 ** min(14.0 if i < 2 else 8.0, base + draw(st.floats(0, 11)))
    lo, hi = sorted([in_range("speed", draw), in_range("speed", draw)])
    sensors = []
    for _ in range(draw(st.integers(1, 2))):
        radar = draw(extreme_radar())
        radar.pop("heading")
        sensors.append(radar)
    return {
        "dt": in_range("dt", draw), "process_noise": in_range("process_noise", draw),
        "map": {"width": W, "height": H},
        "initial": {"speed_range": [lo, hi], "cov": cov},
        "planning": {"planner": draw(st.sampled_from(["random", "pg", "sequential-greedy"])),
                     "horizon": draw(st.integers(1, 2)),
                     "steps_per_epoch": draw(st.integers(1, 2)),
                     "visibility": draw(st.sampled_from(["probabilistic", "mean"]))},
        "tracker": {"model": draw(st.sampled_from(["cv", "imm"])),
                    "process_noise": in_range("process_noise", draw),
                    "miss_update": draw(st.sampled_from(["negative", "none"])),
                    "known_map": draw(st.booleans()),
                    "association": draw(st.sampled_from(["pda", "nearest"]))},
        "run": {"steps": draw(st.integers(2, 6)), "seed": draw(st.integers(0, 100))},
        "targets": [{"kind": draw(st.sampled_from(["cv", "dubins"])),
                     "turn_hold": in_range("turn_hold", draw),
                     "max_turn_rate": in_range("max_turn_rate", draw)}
                    for _ in range(draw(st.integers(1, 3)))],
        "sensors": sensors,
    }
