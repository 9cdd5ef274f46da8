"""Reading input files and writing the single-decision result.

Every failure to read a file becomes a :class:`~sensorplan.errors.ConfigError` whose field is
the file's path, so that the CLI can report it in one line.
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from ..planners import PlanResult

#: Planners whose result carries ``converged`` and ``sweeps``.
GAME_PLANNERS = ("pg", "pg-refine")

#: Output keys in their documented order (docs/cli.md); ``existence`` only when the decision
#: file gives a target's, ``found`` and ``search_term`` only when its search is on.
OUTPUT_KEYS = ("planner", "plan", "potential", "information", "existence", "found",
               "search_term", "converged", "sweeps", "seconds")


#: Deepest nesting of lists and tables an input file may have. The file formats need
#: four levels (a covariance inside a target inside the file); deeper input is refused
#: before anything recurses through it.
MAX_DEPTH = 32
#: Largest input file read (bytes); the example files are about 1 kB.
MAX_FILE_BYTES = 10_000_000


def _read_text(path: str | Path) -> str:
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES and path.is_file():
            raise ConfigError(str(path), f"is too large ({size} bytes; at most "
                              f"{MAX_FILE_BYTES} bytes)")
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(str(path), "no such file") from None
    except IsADirectoryError:
        raise ConfigError(str(path), "is a directory, not a file") from None
    except UnicodeDecodeError:
        raise ConfigError(str(path), "is not UTF-8 text") from None
    except OSError as exc:
        raise ConfigError(str(path), f"cannot be read ({exc.strerror or exc})") from None


class _Duplicate(dict):
    """A JSON object that repeated a key; :func:`check_tree` reports it with its path."""

    duplicate: str = ""


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # json.loads would silently keep the last of two equal keys; a typo should not pass.
    # The hook does not know where the object is, so the object is marked and the walk
    # that follows the parse names the key with its dotted path.
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            marked = _Duplicate(out)
            marked.duplicate = key
            return marked
        out[key] = value
    return out


_SURROGATE = re.compile("[\ud800-\udfff]")


def _has_surrogate(text: str) -> bool:
    return _SURROGATE.search(text) is not None


def _child_path(path: str, key: Any) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


def check_tree(data: Any, source: str) -> None:
    """Refuse what the strict models cannot name well: nesting deeper than
    :data:`MAX_DEPTH` (naming the file), repeated keys and text that is not valid Unicode
    (a lone surrogate, naming the field by its dotted path). Iterative: it never recurses.
    """
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    while stack:
        value, path, depth = stack.pop()
        if isinstance(value, str):
            if _has_surrogate(value):
                raise ConfigError(path or source, "is not valid Unicode text (a lone "
                                  "surrogate)")
            continue
        if not isinstance(value, (dict, list)):
            continue
        if depth >= MAX_DEPTH:
            raise ConfigError(source, f"is nested too deeply (more than {MAX_DEPTH} levels "
                              "of lists and tables)")
        if isinstance(value, dict):
            for key in value:
                if _has_surrogate(str(key)):
                    raise ConfigError(_child_path(path, key), "this key is not valid Unicode "
                                      "text (a lone surrogate)")
            if isinstance(value, _Duplicate):
                raise ConfigError(_child_path(path, value.duplicate), "duplicate key")
            items: Any = value.items()
        else:
            items = enumerate(value)
        stack.extend((v, _child_path(path, k), depth + 1) for k, v in reversed(list(items)))


def read_json(path: str | Path) -> Any:
    """Parse a JSON file; syntax errors and duplicate keys raise :class:`ConfigError`."""
    return parse_json(_read_text(path), str(path))


def parse_json(text: str, source: str = "<json>") -> Any:
    """Parse JSON text (see :func:`read_json`); ``source`` names the input in errors.

    Besides syntax errors, refuses integers of more than 4300 digits (Python's limit for
    converting text to int), nesting deeper than :data:`MAX_DEPTH`, repeated keys and lone
    surrogates (:func:`check_tree`), each as one :class:`ConfigError`.
    """
    try:
        data = json.loads(text, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as exc:
        raise ConfigError(source, f"invalid JSON: {exc.msg} (line {exc.lineno}, "
                          f"column {exc.colno})") from None
    except RecursionError:
        raise ConfigError(source, f"invalid JSON: nested too deeply (more than {MAX_DEPTH} "
                          "levels of lists and objects)") from None
    except ValueError as exc:
        raise ConfigError(source, f"invalid JSON: {_number_message(exc)}") from None
    check_tree(data, source)
    return data


def _number_message(exc: ValueError) -> str:
    """The parser's ValueError other than a syntax error: an over-long integer."""
    text = str(exc)
    if "digits" in text:
        return "a number has too many digits (integers have at most 4300)"
    return text


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; syntax errors raise :class:`ConfigError` naming the file (as do
    over-long integers, deep nesting and lone surrogates, as for :func:`parse_json`)."""
    return parse_toml(_read_text(path), str(path))


def parse_toml(text: str, source: str = "<toml>") -> dict[str, Any]:
    """Parse TOML text (see :func:`read_toml`); ``source`` names the input in errors."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, f"invalid TOML: {exc}") from None
    except RecursionError:
        raise ConfigError(source, f"invalid TOML: nested too deeply (more than {MAX_DEPTH} "
                          "levels of arrays and tables)") from None
    except ValueError as exc:
        raise ConfigError(source, f"invalid TOML: {_number_message(exc)}") from None
    check_tree(data, source)
    return data


# ----------------------------------------------------------- the kinds of input file

#: What each command reads, for the hint when it is given another kind of file.
READS = {
    "decision": "plan reads a single-decision JSON file (sensorplan plan --example prints one)",
    "scenario": "simulate reads a scenario TOML file (see configs/paper.toml)",
    "study": "study reads a study TOML file (see studies/paper.toml)",
    "grid": "grid reads a grid TOML file (see studies/lookahead_map.toml)",
}
#: Each kind of input file, as the hint names it and the command that reads it.
KIND_TEXT = {
    "decision": "a single-decision file: a decision is planned with sensorplan plan",
    "scenario": "a scenario file (it has [[targets]] and [[sensors]]): a scenario is "
                "simulated with sensorplan simulate",
    "study": "a study file (it has runs and [[methods]]): a study is run with sensorplan study",
    "grid": "a grid file (it has [[axes]]): a grid is run with sensorplan grid",
}


def file_kind(data: Any) -> str | None:
    """Which kind of input file parsed ``data`` is, by keys only that kind has (None when
    they do not tell): a grid has ``axes``, a study ``runs`` or ``methods`` and no
    ``targets``, a scenario ``targets`` or ``sensors`` and none of ``runs``, ``methods`` and
    ``horizon``, a decision ``horizon`` and ``targets`` at the top level."""
    if not isinstance(data, dict):
        return None
    keys = set(data)
    if "axes" in keys:
        return "grid"
    if keys & {"runs", "methods"} and not keys & {"targets", "sensors"}:
        return "study"
    if {"horizon", "targets"} <= keys:
        return "decision"
    if keys & {"targets", "sensors"} and not keys & {"runs", "methods", "horizon"}:
        return "scenario"
    return None


def read_input(path: str | Path, kind: str) -> Any:
    """Read input file ``path`` of ``kind`` (a key of :data:`READS`): JSON for a decision,
    TOML for the others.

    A file of another kind, or in the other format, is refused with one line that says what
    the file is, which command reads it and what this one reads (``runs/x.toml: is a study
    file (...): a study is run with sensorplan study; simulate reads a scenario TOML
    file``).

    Raises
    ------
    ConfigError
        Naming the file: unreadable, invalid in both formats (the error of the expected one),
        or a file of another kind.
    """
    text = _read_text(path)
    source = str(path)
    parse, other, other_format = ((parse_json, parse_toml, "TOML") if kind == "decision"
                                  else (parse_toml, parse_json, "JSON"))
    try:
        data = parse(text, source)
    except ConfigError as exc:
        try:
            alt = other(text, source)
        except ConfigError:
            raise exc from None
        found = file_kind(alt)
        what = KIND_TEXT[found] if found is not None and found != kind else \
            f"a {other_format} file"
        raise ConfigError(source, f"is {what}; {READS[kind]}") from None
    # Within TOML the keys tell a scenario, a study and a grid apart; a JSON file is a
    # decision, whatever keys it lacks. A grid is a study with axes: one without them is
    # a grid that lacks its axes (the model says so).
    if kind in ("study", "grid") and not data:
        # Nothing a study could run (an empty or all-comment file): say so of the file, not
        # of the first key it lacks.
        raise ConfigError(source, f"is empty; {READS[kind]}")
    found = file_kind(data) if kind != "decision" else None
    if found == "study" and kind == "grid":
        found = None
    if found is not None and found not in (kind, "decision"):
        raise ConfigError(source, f"is {KIND_TEXT[found]}; {READS[kind]}")
    return data


def result_to_dict(result: PlanResult, existence: Any = None) -> dict[str, Any]:
    """A planner's result as the output object of ``sensorplan plan``.

    Parameters
    ----------
    result : PlanResult
        ``plan.positions (N, K, 2)``, ``plan.targets (N, K)``, ``headings (N, K)`` and
        ``measurements (N, K)`` give ``plan[i][k-1]``; ``seconds`` is the planner's own time.
    existence : (M,) array, optional
        The targets' probabilities of existence, reported when given (the decision file
        gave one).

    Returns
    -------
    dict
        Keys ``planner, plan, potential, information, [existence,] [found, search_term,]
        [converged, sweeps,] seconds``; ``found`` (mu, the expected number of undetected
        targets the plan finds) and ``search_term`` (``w mu``, nats) when the result reports
        them (search on), ``converged`` and ``sweeps`` only for ``pg`` and ``pg-refine``. An
        unassigned player (never in a finished plan) is ``null``. A look has ``target``,
        or ``sector`` when it is a search look.
    """
    plan = result.plan
    N, K = plan.targets.shape
    rows: list[list[dict[str, Any] | None]] = []
    for i in range(N):
        row: list[dict[str, Any] | None] = []
        for k in range(K):
            target = int(plan.targets[i, k])
            sector = -1 if plan.sectors is None else int(plan.sectors[i, k])
            if target < 0 and sector < 0:
                row.append(None)
                continue
            # A look has a target or, when it searches, a sector.
            look = {"target": target} if target >= 0 else {"sector": sector}
            row.append({
                "epoch": k + 1,
                "position": [float(plan.positions[i, k, 0]), float(plan.positions[i, k, 1])],
                "heading": float(result.headings[i, k]),
                **look,
                "measurements": int(result.measurements[i, k]),
            })
        rows.append(row)
    out: dict[str, Any] = {
        "planner": result.planner,
        "plan": rows,
        "potential": float(result.potential),
        "information": [float(v) for v in result.information],
    }
    if existence is not None:
        out["existence"] = [float(v) for v in existence]
    term = getattr(result, "search_term", None)
    if term is not None:
        # Phi = sum(information) + search_term.
        out["found"] = float(result.found)  # type: ignore[arg-type]
        out["search_term"] = float(term)
    if result.planner in GAME_PLANNERS:
        out["converged"] = None if result.converged is None else bool(result.converged)
        out["sweeps"] = None if result.sweeps is None else int(result.sweeps)
    out["seconds"] = float(result.seconds)
    return out


def dumps_result(result: PlanResult, existence: Any = None) -> str:
    """:func:`result_to_dict` as JSON text, one plan entry per line (no trailing newline).

    Non-finite numbers raise ``ValueError``: they are not JSON.
    """
    out = result_to_dict(result, existence)
    items = []
    for key, value in out.items():
        if key == "plan" and value:
            rows = []
            for row in value:
                entries = ",\n".join("      " + json.dumps(a, allow_nan=False) for a in row)
                rows.append("    [\n" + entries + "\n    ]" if row else "    []")
            text = "[\n" + ",\n".join(rows) + "\n  ]"
        else:
            text = json.dumps(value, allow_nan=False)
        items.append(f"  {json.dumps(key)}: {text}")
    return "{\n" + ",\n".join(items) + "\n}"


def ensure_out_dir(out: Path, field: str = "--out") -> None:
    """Create the output directory ``out`` and check that files can be written in it.

    Raises
    ------
    ConfigError
        Naming ``field``: ``out`` is a file, cannot be created, or is not writable (checked
        by creating and removing a temporary file, before any work is done).
    """
    import tempfile

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(field, f"{out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(field, f"cannot create {out} ({exc.strerror or exc})") from None
    try:
        with tempfile.TemporaryFile(dir=out, prefix=".sensorplan-write-test-"):
            pass
    except OSError as exc:
        raise ConfigError(field, f"cannot write in {out} ({exc.strerror or exc})") from None


def write_failed(exc: OSError, field: str = "--out", where: str | Path | None = None
                 ) -> ConfigError:
    """The one-line error of an output file that could not be written (a full disk, a
    directory where the file should go, lost permissions), naming ``field`` and the file
    (else ``where``, the place being written)."""
    target = getattr(exc, "filename", None) or where
    place = f"{target}: " if target else ""
    return ConfigError(field, f"cannot write {place}{exc.strerror or exc}")
