"""Reading input files and writing the single-decision result (SPEC 7).

Every failure to read a file becomes a :class:`~sensorplan.errors.ConfigError` whose field is
the file's path, so that the CLI can report it in one line.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from .planners import PlanResult

#: Planners whose result carries ``converged`` and ``sweeps`` (SPEC 7).
GAME_PLANNERS = ("pg", "pg-refine")

#: Output keys in SPEC 7 order.
OUTPUT_KEYS = ("planner", "plan", "potential", "information", "converged", "sweeps", "seconds")


def _read_text(path: str | Path) -> str:
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(str(path), "no such file") from None
    except IsADirectoryError:
        raise ConfigError(str(path), "is a directory, not a file") from None
    except UnicodeDecodeError:
        raise ConfigError(str(path), "is not UTF-8 text") from None
    except OSError as exc:
        raise ConfigError(str(path), f"cannot be read ({exc.strerror or exc})") from None


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # json.loads would silently keep the last of two equal keys; a typo should not pass.
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ConfigError(key, "duplicate key")
        out[key] = value
    return out


def read_json(path: str | Path) -> Any:
    """Parse a JSON file; syntax errors and duplicate keys raise :class:`ConfigError`."""
    return parse_json(_read_text(path), str(path))


def parse_json(text: str, source: str = "<json>") -> Any:
    """Parse JSON text (see :func:`read_json`); ``source`` names the input in errors."""
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as exc:
        raise ConfigError(source, f"invalid JSON: {exc.msg} (line {exc.lineno}, "
                          f"column {exc.colno})") from None


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; syntax errors raise :class:`ConfigError` naming the file."""
    text = _read_text(path)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), f"invalid TOML: {exc}") from None


def result_to_dict(result: "PlanResult") -> dict[str, Any]:
    """A planner's result as the SPEC 7 output object.

    Parameters
    ----------
    result : PlanResult
        ``plan.positions (N, K, 2)``, ``plan.targets (N, K)``, ``headings (N, K)`` and
        ``measurements (N, K)`` give ``plan[i][k-1]``; ``seconds`` is the planner's own time.

    Returns
    -------
    dict
        Keys ``planner, plan, potential, information, [converged, sweeps,] seconds``;
        ``converged`` and ``sweeps`` only for ``pg`` and ``pg-refine``. An unassigned player
        (never in a finished plan) is ``null``.
    """
    plan = result.plan
    N, K = plan.targets.shape
    rows: list[list[dict[str, Any] | None]] = []
    for i in range(N):
        row: list[dict[str, Any] | None] = []
        for k in range(K):
            target = int(plan.targets[i, k])
            if target < 0:
                row.append(None)
                continue
            row.append({
                "epoch": k + 1,
                "position": [float(plan.positions[i, k, 0]), float(plan.positions[i, k, 1])],
                "heading": float(result.headings[i, k]),
                "target": target,
                "measurements": int(result.measurements[i, k]),
            })
        rows.append(row)
    out: dict[str, Any] = {
        "planner": result.planner,
        "plan": rows,
        "potential": float(result.potential),
        "information": [float(v) for v in result.information],
    }
    if result.planner in GAME_PLANNERS:
        out["converged"] = None if result.converged is None else bool(result.converged)
        out["sweeps"] = None if result.sweeps is None else int(result.sweeps)
    out["seconds"] = float(result.seconds)
    return out


def dumps_result(result: "PlanResult") -> str:
    """:func:`result_to_dict` as JSON text, one plan entry per line (no trailing newline).

    Non-finite numbers raise ``ValueError``: they are not JSON.
    """
    out = result_to_dict(result)
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


def ensure_out_dir(out: Path) -> None:
    """Create the output directory ``out``; a ConfigError naming ``--out`` if impossible."""
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", f"{out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError("--out", f"cannot create {out} ({exc.strerror or exc})") from None
