"""Resumable storage of a study directory: parts written atomically, a lock, metadata,
consolidation into the tidy tables, and reading everything back.

Each finished (run, method) is written at once as three small Parquet files (temp name,
then rename), so a study killed at any moment resumes with the same command and never
recomputes what is done; the directory layout and the resume rules are in docs/studies.md.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import platform
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .model import FORMAT, READABLE_FORMATS, Study, planned_as_written
from .set_metrics import GOSPA_CUTOFF
from .tables import TABLES, TaskResult, arrow_table

#: Keys of config.resolved.json that decide the results (a resumed study must match them).
RESULT_KEYS = ("format", "runs", "steps", "gospa_c", "seed", "scenario", "methods")
#: Their values in a study directory written before the key existed.
RESULT_DEFAULTS = {"gospa_c": GOSPA_CUTOFF}
#: Method settings added since, with the value every method written before them ran with.
#: What a method written before a per-method setting existed ran with.
METHOD_DEFAULTS = {"reward": "information", "unreported": "localise", "find_tail": 0,
                   "track_existence": "fixed"}


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


def _settings_read(method: Any) -> Any:
    """A resolved method without the tracker settings its tracker does not read
    (:meth:`~sensorplan.simulation.settings.TrackerSettings.unused`): a change of such a
    setting (a preset's IMM modes, for a method that runs one motion model) changes nothing
    that ran, so the directory still holds the same study."""
    if not (isinstance(method, dict) and isinstance(method.get("tracker"), dict)):
        return method
    from ..simulation.settings import TrackerSettings

    try:
        unused = set(TrackerSettings(**method["tracker"]).unused())
    except (TypeError, ValueError, ConfigError):
        return method                       # not a tracker this version can read: as is
    return {**method, "tracker": {k: v for k, v in method["tracker"].items()
                                  if k not in unused}}


def part_path(out: Path, run: int, method: int, table: str) -> Path:
    """File of one (run, method)'s table: ``parts/run-00007/m03.steps.parquet``."""
    return Path(out) / "parts" / f"run-{run:05d}" / f"m{method:02d}.{table}.parquet"


def _atomic_write(path: Path, write: Callable[[Path], object]) -> None:
    """Write through a temporary name in the same directory, then rename.

    ``os.replace`` is atomic on POSIX, so readers (and a resumed study) see either the whole
    file or none of it, whatever moment the process is killed at.
    """
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.errno is not None:
            # Named by the file meant (a directory in its place, a full disk), not the
            # temporary name.
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise


def _write_json(path: Path, data: Any) -> None:
    def write(tmp: Path) -> None:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")
    _atomic_write(path, write)


def _parquet_bytes(table: Any) -> bytes:
    import pyarrow as pa
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _write_bytes(path: Path, data: bytes) -> None:
    _atomic_write(path, lambda tmp: tmp.write_bytes(data))


def sums_path(out: Path, run: int, method: int) -> Path:
    """The checksums of one (run, method)'s files: ``parts/run-00007/m03.sha256``."""
    return Path(out) / "parts" / f"run-{run:05d}" / f"m{method:02d}.sha256"


def write_part(out: Path, result: TaskResult) -> None:
    """Write one (run, method)'s tables, each atomically, with their SHA-256 checksums.

    The checksums (``mNN.sha256``) are written before the ``steps`` file, whose presence
    marks the part done: a done part can always be verified.
    """
    path = part_path(out, result.run, result.method, TABLES[0])
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {t: _parquet_bytes(arrow_table(result.tables[t])) for t in TABLES}
    sums = {t: _digest(b) for t, b in data.items()}
    for table in TABLES[:-1]:
        _write_bytes(part_path(out, result.run, result.method, table), data[table])
    _write_json(sums_path(out, result.run, result.method), sums)
    _write_bytes(part_path(out, result.run, result.method, TABLES[-1]), data[TABLES[-1]])


def _read_sums(path: Path) -> dict[str, str] | None:
    try:
        sums = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(sums, dict) or not all(isinstance(sums.get(t), str) for t in TABLES):
        return None
    return sums


def part_problem(out: Path, run: int, method: int) -> str | None:
    """What is wrong with a part whose ``steps`` file exists (None: it is intact).

    A part with checksums is intact when every file matches its checksum; a part written
    before checksums existed when pyarrow can read every file.
    """
    sums_file = sums_path(out, run, method)
    if not sums_file.exists():
        import pyarrow.parquet as pq

        for table in TABLES:
            path = part_path(out, run, method, table)
            try:
                pq.read_metadata(path)
            except Exception as exc:  # noqa: BLE001 - any failure to read is damage
                return f"{path.name} cannot be read ({type(exc).__name__})"
        return None
    sums = _read_sums(sums_file)
    if sums is None:
        return f"{sums_file.name} is damaged"
    for table in TABLES:
        path = part_path(out, run, method, table)
        try:
            data = path.read_bytes()
        except OSError as exc:
            return f"{path.name} cannot be read ({exc.strerror or exc})"
        if _digest(data) != sums[table]:
            return f"{path.name} does not match its checksum"
    return None


def check_parts(out: Path, study: Study) -> tuple[set[tuple[int, int]],
                                                  dict[tuple[int, int], str]]:
    """The intact done (run, method) pairs, and the damaged ones with what is wrong.

    A pair without its ``steps`` file is neither (it is still to run).
    """
    done: set[tuple[int, int]] = set()
    damaged: dict[tuple[int, int], str] = {}
    for r, m in study.tasks():
        if not part_path(out, r, m, TABLES[-1]).exists():
            continue
        problem = part_problem(out, r, m)
        if problem is None:
            done.add((r, m))
        else:
            damaged[(r, m)] = problem
    return done, damaged


def remove_part(out: Path, run: int, method: int) -> None:
    """Delete one (run, method)'s files (a damaged part, before it is run again)."""
    for path in [part_path(out, run, method, t) for t in TABLES] + [sums_path(out, run, method)]:
        try:
            path.unlink()
        except FileNotFoundError:
            pass
        except OSError as exc:                  # a directory in its place, no permission
            raise ConfigError("--out", f"cannot remove the damaged part file {path} "
                              f"({exc.strerror or exc}); delete it and run the same command "
                              "again") from None


def done_tasks(out: Path, study: Study) -> set[tuple[int, int]]:
    """(run, method) pairs whose files are all on disk and intact (:func:`check_parts`)."""
    return check_parts(out, study)[0]


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
    return datetime.now(UTC).isoformat(timespec="seconds")


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


def _read_resolved(config: Path, field: str, fix: str,
                   formats: tuple[str, ...] = (FORMAT,)) -> Any:
    """The content of a ``config.resolved.json``; a ConfigError naming ``field`` if it cannot
    be read or has a layout version not in ``formats`` (``fix``: what to do about that)."""
    try:
        data = json.loads(config.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(field, f"{config} cannot be read ({exc})") from None
    if isinstance(data, dict) and data.get("format") not in formats:
        raise ConfigError(field, f"{config.parent} was written by another sensorplan version "
                          f"(format {data.get('format')!r}, this one uses {FORMAT!r}); {fix}")
    return data


def prepare(out: Path, study: Study) -> int | None:
    """Create ``out`` or check that it holds this study; raise ConfigError otherwise.

    The study may have more runs than the one in ``out`` (and nothing else changed): the
    directory then becomes the larger study (its finished runs are kept; run seeds do not
    depend on the number of runs) and the previous number of runs is returned, else None.
    """
    resolved = study.resolved()
    config = out / "config.resolved.json"
    if config.exists():
        old = _read_resolved(config, "--out", "use another --out or delete it")
        before = {k: old.get(k, RESULT_DEFAULTS.get(k)) for k in RESULT_KEYS}
        if isinstance(before["methods"], list):
            before["methods"] = [{**METHOD_DEFAULTS, **planned_as_written(m)}
                                 if isinstance(m, dict) and isinstance(m.get("tracker", {}), dict)
                                 else m
                                 for m in before["methods"]]
        after: dict[str, Any] = {k: resolved.get(k) for k in RESULT_KEYS}
        for side in (before, after):
            if isinstance(side["methods"], list):
                side["methods"] = [_settings_read(m) for m in side["methods"]]
        grown = (isinstance(before["runs"], int) and not isinstance(before["runs"], bool)
                 and after["runs"] > before["runs"])
        if grown:
            before["runs"] = after["runs"]
        diffs = differences(before, after)
        if diffs:
            shown = "; ".join(diffs[:3]) + ("; ..." if len(diffs) > 3 else "")
            raise ConfigError("--out", f"{out} holds results of a different study "
                              f"(changed: {shown}); use another --out or delete it (only "
                              "runs may be raised)")
        if not grown:
            return None
        # The tables of fewer runs are not this study's: remove them before the new
        # configuration is written, so that no moment leaves them looking complete.
        for path in [out / f"{t}.parquet" for t in TABLES] + [out / TABLE_SUMS]:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        _write_json(config, {**old, "runs": resolved["runs"]})
        return int(old["runs"])
    others = [p.name for p in out.iterdir() if p.name != ".lock"]
    if others:
        raise ConfigError("--out", f"{out} is not empty and is not a study directory "
                          f"(no config.resolved.json)")
    _write_json(config, resolved)
    return None


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


#: Checksums of the consolidated tables (and the runs they hold).
TABLE_SUMS = "tables.sha256"


class DamagedPart(ConfigError):
    """A part changed after it was written (found while reading it back)."""


def _read_part(out: Path, run: int, method: int, table: str, sums: dict[str, str] | None
               ) -> Any:
    """One part's table, verified against its checksum when it has one."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = part_path(out, run, method, table)
    data = path.read_bytes()
    if sums is not None and _digest(data) != sums.get(table):
        raise DamagedPart("--out", f"{path} changed after it was written (checksum "
                          "mismatch); run the same command again to recompute it")
    return pq.read_table(pa.BufferReader(data))


def read_parts(out: Path, tasks: list[tuple[int, int]]) -> dict[str, Any]:
    """The tables of ``tasks`` (run, method) from their parts, verified, in that order."""
    import pyarrow as pa

    sums = {(r, m): _read_sums(sums_path(out, r, m)) for r, m in tasks}
    # Promoted: only a tracker with an undetected intensity adds its columns to ``gospa``;
    # the other methods' rows get nulls there.
    return {t: pa.concat_tables([_read_part(out, r, m, t, sums[(r, m)]) for r, m in tasks],
                                promote_options="default")
            for t in TABLES}


def consolidate(out: Path, study: Study) -> None:
    """Write ``steps/decisions/sensors.parquet`` from the verified parts, in (run, method)
    order, and their checksums (``tables.sha256``)."""
    tables = read_parts(out, study.tasks())
    with contextlib.suppress(FileNotFoundError):
        (out / TABLE_SUMS).unlink()
    sums: dict[str, Any] = {"runs": study.runs}
    for table in TABLES:
        data = _parquet_bytes(tables[table])
        sums[table] = _digest(data)
        _write_bytes(out / f"{table}.parquet", data)
    _write_json(out / TABLE_SUMS, sums)


def tables_intact(out: Path, study: Study) -> bool:
    """Whether the consolidated tables exist, hold ``study``'s runs and match their
    checksums."""
    try:
        sums = json.loads((out / TABLE_SUMS).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    if not isinstance(sums, dict) or sums.get("runs") != study.runs:
        return False
    for table in TABLES:
        try:
            data = (out / f"{table}.parquet").read_bytes()
        except OSError:
            return False
        if _digest(data) != sums.get(table):
            return False
    return True


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
    method that has started. Methods without a finished run are left out of ``study``
    and the tables, and named in ``methods_missing``.
    """

    study: Study
    meta: dict[str, Any]
    steps: Any
    decisions: Any
    sensors: Any
    tracks: Any
    gospa: Any
    complete: bool
    runs_done: list[int]
    methods_missing: list[str] = field(default_factory=list)


def load_study_dir(out: str | Path) -> StudyTables:
    """Read a study directory written by :func:`~sensorplan.study.run_study` (complete or not).

    Raises
    ------
    ConfigError
        ``out`` is not a study directory or holds no finished run.
    """
    import pandas as pd
    import pyarrow.parquet as pq

    out = Path(out)
    config = out / "config.resolved.json"
    if not config.exists():
        raise ConfigError("DIR", f"{out} is not a study directory (no config.resolved.json)")
    data = _read_resolved(config, "DIR", "run the study again into a new directory",
                          READABLE_FORMATS)
    try:
        study = Study.from_resolved(data)
    except (ValueError, KeyError, TypeError) as exc:
        raise ConfigError("DIR", f"{config} cannot be read ({exc})") from None
    meta = _read_meta(out)
    missing: list[str] = []
    if tables_intact(out, study):
        complete = True
        frames = {t: pq.read_table(out / f"{t}.parquet").to_pandas() for t in TABLES}
        runs_done = list(range(study.runs))
    else:
        # Unfinished, or tables that are damaged or older than checksums: the parts.
        done, damaged = check_parts(out, study)
        for (r, m), problem in sorted(damaged.items()):
            sys.stderr.write(f"warning: {part_path(out, r, m, 'steps').parent.name}/m{m:02d} "
                             f"of {out} is damaged ({problem}); its run is left out (run the "
                             "study command again to recompute it)\n")
        # A method with no finished run has not been started (a study run some methods
        # at a time): it is left out rather than leaving no run finished by every method.
        ran = [m for m in range(len(study.methods)) if any((r, m) in done
                                                           for r in range(study.runs))]
        missing = [study.methods[m].name for m in range(len(study.methods)) if m not in ran]
        runs_done = [r for r in range(study.runs) if ran and all((r, m) in done for m in ran)]
        if not runs_done:
            raise ConfigError("DIR", f"{out} holds no run finished by every method yet")
        complete = len(runs_done) == study.runs and not missing
        tasks = [(r, m) for r in runs_done for m in ran]
        study = dataclasses.replace(study, methods=tuple(study.methods[m] for m in ran))
        try:
            frames = {t: tab.to_pandas() for t, tab in read_parts(out, tasks).items()}
        except DamagedPart as exc:
            raise ConfigError("DIR", exc.message) from None
    if "label" not in frames["sensors"]:
        # An older layout: the look's index is the target's for a tracker of known targets
        # and not a label otherwise.
        known = [m.name for m in study.methods if m.settings.tracker.kind == "known"]
        sensors = frames["sensors"]
        sensors["label"] = sensors["target"].where(sensors["method"].isin(known), -1)
    order = pd.CategoricalDtype(study.method_names, ordered=True)
    for df in frames.values():
        df["method"] = df["method"].astype(order)
    # The kinds of the scenario's targets and of those a run recorded (a scripted truth has
    # no templates; its targets' kinds are the run's).
    kinds = set(study.scenario.target_kinds) | set(frames["steps"]["kind"].dropna().unique())
    frames["steps"]["kind"] = frames["steps"]["kind"].astype(
        pd.CategoricalDtype(sorted(kinds), ordered=True))
    return StudyTables(study, meta, frames["steps"], frames["decisions"], frames["sensors"],
                       frames["tracks"], frames["gospa"], complete, runs_done, missing)
