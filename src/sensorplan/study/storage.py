"""Resumable storage of a study directory: parts written atomically, a lock, metadata,
consolidation into the tidy tables, and reading everything back.

Each finished (run, method) is written at once as three small Parquet files (temp name,
then rename), so a study killed at any moment resumes with the same command and never
recomputes what is done; the directory layout and the resume rules are in docs/studies.md.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import subprocess
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .model import FORMAT, Study
from .tables import TABLES, TaskResult, arrow_table


#: Keys of config.resolved.json that decide the results (a resumed study must match them).
RESULT_KEYS = ("format", "runs", "steps", "seed", "scenario", "methods")


def differences(old: Any, new: Any, path: str = "") -> list[str]:
    """Dotted paths at which two JSON values differ."""
    if isinstance(old, dict) and isinstance(new, dict):
        out: list[str] = []
        for k in list(old) + [k for k in new if k not in old]:
            p = f"{path}.{k}" if path else str(k)
            if k not in old or k not in new:
                out.append(p)
            else:
                out += differences(old[k], new[k], p)
        return out
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return [f"{path} (length {len(old)} -> {len(new)})"]
        return [d for i, (a, b) in enumerate(zip(old, new))
                for d in differences(a, b, f"{path}[{i}]")]
    return [] if old == new else [f"{path} ({json.dumps(old)} -> {json.dumps(new)})"]


def part_path(out: Path, run: int, method: int, table: str) -> Path:
    """File of one (run, method)'s table: ``parts/run-00007/m03.steps.parquet``."""
    return Path(out) / "parts" / f"run-{run:05d}" / f"m{method:02d}.{table}.parquet"


def _atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Write through a temporary name in the same directory, then rename.

    ``os.replace`` is atomic on POSIX, so readers (and a resumed study) see either the whole
    file or none of it, whatever moment the process is killed at.
    """
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_json(path: Path, data: Any) -> None:
    def write(tmp: Path) -> None:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")
    _atomic_write(path, write)


def write_part(out: Path, result: TaskResult) -> None:
    import pyarrow.parquet as pq

    for table in TABLES:                   # "steps" last: its presence marks the part done
        path = part_path(out, result.run, result.method, table)
        path.parent.mkdir(parents=True, exist_ok=True)
        tab = arrow_table(result.tables[table])
        _atomic_write(path, lambda tmp, tab=tab: pq.write_table(tab, tmp))


def done_tasks(out: Path, study: Study) -> set[tuple[int, int]]:
    """(run, method) pairs whose files are all on disk."""
    return {(r, m) for r, m in study.tasks()
            if part_path(out, r, m, TABLES[-1]).exists()}


def versions() -> dict[str, str]:
    from importlib import metadata

    out = {"python": platform.python_version()}
    for pkg in ("sensorplan", "numpy", "scipy", "numba", "pyarrow", "pandas", "dask",
                "distributed", "pydantic", "rich"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            out[pkg] = metadata.version(pkg)
    return out


def git_describe() -> str | None:
    here = Path(__file__).resolve().parent
    try:
        res = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"], cwd=here,
                             capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return res.stdout.strip() or None if res.returncode == 0 else None


def now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


@contextlib.contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out/.lock`` (released by the OS even on SIGKILL)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise ConfigError("--out", f"{out} is in use by another sensorplan study "
                              "process") from None
        yield
    finally:
        os.close(fd)


def _read_resolved(config: Path, field: str, fix: str) -> Any:
    """The content of a ``config.resolved.json``; a ConfigError naming ``field`` if it cannot
    be read or has another layout version (``fix``: what to do about that)."""
    try:
        data = json.loads(config.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(field, f"{config} cannot be read ({exc})") from None
    if isinstance(data, dict) and data.get("format") != FORMAT:
        raise ConfigError(field, f"{config.parent} was written by another sensorplan version "
                          f"(format {data.get('format')!r}, this one uses {FORMAT!r}); {fix}")
    return data


def prepare(out: Path, study: Study) -> None:
    """Create ``out`` or check that it holds this study; raise ConfigError otherwise."""
    resolved = study.resolved()
    config = out / "config.resolved.json"
    if config.exists():
        old = _read_resolved(config, "--out", "use another --out or delete it")
        diffs = differences({k: old.get(k) for k in RESULT_KEYS},
                            {k: resolved.get(k) for k in RESULT_KEYS})
        if diffs:
            shown = "; ".join(diffs[:3]) + ("; ..." if len(diffs) > 3 else "")
            raise ConfigError("--out", f"{out} holds results of a different study "
                              f"(changed: {shown}); use another --out or delete it")
        return
    others = [p.name for p in out.iterdir() if p.name != ".lock"]
    if others:
        raise ConfigError("--out", f"{out} is not empty and is not a study directory "
                          f"(no config.resolved.json)")
    _write_json(config, resolved)


def _read_meta(out: Path) -> dict[str, Any]:
    try:
        return json.loads((out / "meta.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def write_meta(out: Path, study: Study, session: dict[str, Any], complete: bool) -> None:
    meta = _read_meta(out)
    sessions = [s for s in meta.get("sessions", []) if s.get("id") != session["id"]]
    sessions.append(session)
    meta.update({
        "format": FORMAT, "versions": versions(), "git": git_describe(),
        "platform": platform.platform(), "machine": platform.machine(),
        "processor": platform.processor() or None, "cpu_count": os.cpu_count(),
        "seed": study.seed, "root_entropy": study.seed, "runs": study.runs,
        "methods": study.method_names, "complete": complete,
        "wall_seconds": round(sum(s.get("wall_seconds", 0.0) for s in sessions), 3),
        "sessions": sessions,
    })
    _write_json(out / "meta.json", meta)


def consolidate(out: Path, study: Study) -> None:
    """Write ``steps/decisions/sensors.parquet`` from the parts, in (run, method) order."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tasks = study.tasks()
    for table in TABLES:
        tab = pa.concat_tables([pq.read_table(part_path(out, r, m, table)) for r, m in tasks])
        _atomic_write(out / f"{table}.parquet", lambda tmp, tab=tab: pq.write_table(tab, tmp))


def clean_temporaries(out: Path) -> None:
    parts = out / "parts"
    if parts.exists():
        for tmp in parts.glob("run-*/.*.tmp*"):
            with contextlib.suppress(OSError):
                tmp.unlink()
    for tmp in out.glob(".*.tmp*"):
        with contextlib.suppress(OSError):
            tmp.unlink()


@dataclass
class StudyTables:
    """A study directory read back: the study, its metadata and its tables (pandas).

    ``complete`` is False when some (run, method) pairs are missing; the tables then hold
    the finished ones (read from the parts) and ``runs_done`` the runs finished by every
    method.
    """

    study: Study
    meta: dict[str, Any]
    steps: Any
    decisions: Any
    sensors: Any
    complete: bool
    runs_done: list[int]


def load_study_dir(out: str | Path) -> StudyTables:
    """Read a study directory written by :func:`~sensorplan.study.run_study` (complete or not).

    Raises
    ------
    ConfigError
        ``out`` is not a study directory or holds no finished run.
    """
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = Path(out)
    config = out / "config.resolved.json"
    if not config.exists():
        raise ConfigError("DIR", f"{out} is not a study directory (no config.resolved.json)")
    data = _read_resolved(config, "DIR", "run the study again into a new directory")
    try:
        study = Study.from_resolved(data)
    except (ValueError, KeyError, TypeError) as exc:
        raise ConfigError("DIR", f"{config} cannot be read ({exc})") from None
    meta = _read_meta(out)
    complete = all((out / f"{t}.parquet").exists() for t in TABLES)
    if complete:
        frames = {t: pq.read_table(out / f"{t}.parquet").to_pandas() for t in TABLES}
        runs_done = list(range(study.runs))
    else:
        done = done_tasks(out, study)
        runs_done = [r for r in range(study.runs)
                     if all((r, m) in done for m in range(len(study.methods)))]
        if not runs_done:
            raise ConfigError("DIR", f"{out} holds no run finished by every method yet")
        tasks = [(r, m) for r in runs_done for m in range(len(study.methods))]
        frames = {t: pa.concat_tables([pq.read_table(part_path(out, r, m, t))
                                       for r, m in tasks]).to_pandas() for t in TABLES}
    order = pd.CategoricalDtype(study.method_names, ordered=True)
    for df in frames.values():
        df["method"] = df["method"].astype(order)
    frames["steps"]["kind"] = frames["steps"]["kind"].astype(
        pd.CategoricalDtype(sorted(set(study.scenario.target_kinds)), ordered=True))
    return StudyTables(study, meta, frames["steps"], frames["decisions"], frames["sensors"],
                       complete, runs_done)
