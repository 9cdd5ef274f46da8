"""Studies under faults and changes: damaged parts, more runs, SIGTERM, a lost Dask
cluster, honest planning times and progress lines whose ETA leaves out the start-up."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

from cli_helpers import assert_bad_input, run
from sensorplan import study as studies
from sensorplan.cli.console import FIRST_LINE_SECONDS, PlainProgress
from sensorplan.study import parse_study
from sensorplan.study.storage import TABLE_SUMS, part_path, sums_path

ROOT = Path(__file__).resolve().parents[2]

TEXT = """
runs = 3
steps = 8
seed = 5
[[methods]]
name = "random"
planner = "random"
[[methods]]
name = "myopic"
planner = "pg"
"""


def frames(out: Path, runs: list[int] | None = None) -> dict[str, pd.DataFrame]:
    t = studies.load_study_dir(out)
    got = {"steps": t.steps, "decisions": t.decisions.drop(columns="planning_seconds"),
           "sensors": t.sensors, "tracks": t.tracks, "gospa": t.gospa}
    if runs is not None:
        got = {k: v[v["run"].isin(runs)].reset_index(drop=True) for k, v in got.items()}
    return got


def assert_same(a: dict[str, pd.DataFrame], b: dict[str, pd.DataFrame]) -> None:
    for name in a:
        pd.testing.assert_frame_equal(a[name], b[name], check_exact=True, obj=name,
                                      check_categorical=False)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "study"
    studies.run_study(parse_study(TEXT), out, workers=1)
    return out


# ---------------------------------------------------------------------- damaged parts


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


def _flip(path: Path, n: int = 16) -> None:
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    for k in range(mid, mid + n):
        data[k] ^= 0xFF
    path.write_bytes(bytes(data))


DAMAGES = {
    "flipped bytes": _flip,
    "truncated": lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "empty": lambda p: p.write_bytes(b""),
    "random bytes": lambda p: p.write_bytes(np.random.default_rng(0).bytes(500)),
}


@pytest.mark.parametrize("damage", sorted(DAMAGES))
@pytest.mark.parametrize("table", ["steps", "decisions"])
def test_a_damaged_part_is_run_again(reference, tmp_path, capsys, damage, table) -> None:
    out = _copy(reference, tmp_path / "study")
    for t in ("steps", "decisions", "sensors"):
        (out / f"{t}.parquet").unlink()                  # the tables gone
    DAMAGES[damage](part_path(out, 1, 1, table))
    study_file = tmp_path / "s.toml"
    study_file.write_text(TEXT)
    code, stdout, err = run(capsys, "study", study_file, "--out", out, "--workers", "1")
    assert code == 0, err
    assert "ran 1 of 6" in stdout                        # only the damaged pair
    warning = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert len(warning) == 1 and "run-00001/m01 is damaged" in warning[0]
    assert_same(frames(out), frames(reference))


def test_report_leaves_a_damaged_run_out(reference, tmp_path, capsys) -> None:
    out = _copy(reference, tmp_path / "study")
    (out / "steps.parquet").unlink()
    _flip(part_path(out, 2, 0, "sensors"))
    t = studies.load_study_dir(out)
    err = capsys.readouterr().err
    assert "run-00002/m00" in err and "left out" in err
    assert not t.complete and t.runs_done == [0, 1]


def test_damaged_tables_are_rebuilt_and_not_trusted(reference, tmp_path, capsys) -> None:
    out = _copy(reference, tmp_path / "study")
    _flip(out / "steps.parquet")
    t = studies.load_study_dir(out)                       # read from the parts instead
    assert t.complete
    assert_same(frames(out), frames(reference))
    res = studies.run_study(parse_study(TEXT), out, workers=1)
    assert res.ran == 0
    sums = json.loads((out / TABLE_SUMS).read_text())
    import hashlib
    assert hashlib.sha256((out / "steps.parquet").read_bytes()).hexdigest() == sums["steps"]
    assert_same(frames(out), frames(reference))


def test_parts_without_checksums_are_still_read(reference, tmp_path) -> None:
    # A directory written before checksums existed: readable parts are trusted as before.
    out = _copy(reference, tmp_path / "study")
    for r in range(3):
        for m in range(2):
            sums_path(out, r, m).unlink()
    (out / TABLE_SUMS).unlink()
    assert studies.done_tasks(out, parse_study(TEXT)) == set(parse_study(TEXT).tasks())
    assert studies.run_study(parse_study(TEXT), out, workers=1).ran == 0
    assert_same(frames(out), frames(reference))


# -------------------------------------------------------------------------- more runs


def test_raising_runs_computes_only_the_new_runs(reference, tmp_path, capsys) -> None:
    out = tmp_path / "grown"
    studies.run_study(parse_study(TEXT.replace("runs = 3", "runs = 2")), out, workers=1)
    three = frames(out)
    f = tmp_path / "s.toml"
    f.write_text(TEXT)
    code, stdout, err = run(capsys, "study", f, "--out", out, "--workers", "1")
    assert code == 0, err
    assert "ran 2 of 6" in stdout and "adding runs 2..2" in err
    grown = frames(out)
    assert_same(grown, frames(reference))                 # = a direct 3-run study
    assert_same(frames(reference, [0, 1]), three)         # its first runs = the 2-run one
    meta = json.loads((out / "meta.json").read_text())
    assert meta["runs"] == 3 and meta["sessions"][-1]["tasks_run"] == 2
    assert json.loads((out / "config.resolved.json").read_text())["runs"] == 3
    # Fewer runs, or another change with more runs, is still a different study.
    f.write_text(TEXT.replace("runs = 3", "runs = 2"))
    assert "runs (3 -> 2)" in assert_bad_input(run(capsys, "study", f, "--out", out), "--out")
    f.write_text(TEXT.replace("runs = 3", "runs = 4").replace("seed = 5", "seed = 6"))
    line = assert_bad_input(run(capsys, "study", f, "--out", out), "--out")
    assert "seed (5 -> 6)" in line


def test_growing_an_interrupted_study_keeps_its_parts(tmp_path) -> None:
    out = tmp_path / "s"
    small = parse_study(TEXT.replace("runs = 3", "runs = 1"))
    studies.run_study(small, out, workers=1)
    assert (out / "steps.parquet").exists()
    big = parse_study(TEXT)
    from sensorplan.study.storage import prepare

    assert prepare(out, big) == 1
    # The 1-run tables are gone at once: they are not the 3-run study's.
    assert not (out / "steps.parquet").exists() and not (out / TABLE_SUMS).exists()
    assert studies.done_tasks(out, big) == {(0, 0), (0, 1)}


# ------------------------------------------------------------------ SIGTERM on a study


def _children(pid: int) -> set[int]:
    """Every descendant of ``pid`` (Linux /proc)."""
    kids: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d.name))
    out: set[int] = set()
    todo = [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigterm_stops_the_study_and_every_worker(tmp_path) -> None:
    f = tmp_path / "s.toml"
    f.write_text(TEXT.replace("runs = 3", "runs = 12").replace("steps = 8", "steps = 40"))
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.Popen([sys.executable, "-m", "sensorplan", "study", str(f), "--out",
                             str(out), "--workers", "2"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    study = parse_study(f.read_text())
    seen: set[int] = set()
    deadline = time.monotonic() + 180
    while not (out.exists() and studies.done_tasks(out, study)):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no pair finished in 180 s"
        seen |= _children(proc.pid)
        time.sleep(0.05)
    seen |= _children(proc.pid)
    assert len(seen) >= 3                      # 2 pool workers and the resource tracker
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 143, stderr
    lines = stderr.splitlines()
    assert lines[-1].startswith("interrupted: ") and "run the same command again" in lines[-1]
    assert "Traceback" not in stderr
    deadline = time.monotonic() + 30          # the pool's processes end after their parent
    while [p for p in seen if _alive(p)] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert [p for p in seen if _alive(p)] == []
    # What was saved resumes.
    done = len(studies.done_tasks(out, study))
    assert f"interrupted: {done} of 24" in lines[-1]


# -------------------------------------------------------------- Dask loses the study


def test_a_lost_dask_cluster_is_one_line(tmp_path, capsys, monkeypatch) -> None:
    from concurrent.futures import CancelledError

    from sensorplan.study import execution

    class LostFuture:
        def result(self) -> None:
            raise CancelledError("_dask_task-1 cancelled for reason: already forgotten")

    class FakeClient:
        def scatter(self, study, broadcast):
            return study

        def submit(self, *args, **kwargs):
            return LostFuture()

        def cancel(self, futures):
            pass

        def close(self):
            pass

    monkeypatch.setattr(execution, "_dask_client", lambda *a: (FakeClient(), None))
    import distributed

    monkeypatch.setattr(distributed, "as_completed", lambda futures: iter(futures))
    f = tmp_path / "s.toml"
    f.write_text(TEXT)
    code, out, err = run(capsys, "study", f, "--out", tmp_path / "o", "--scheduler",
                         "tcp://127.0.0.1:1")
    assert code == 1 and out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: --scheduler: the Dask cluster lost the study")
    assert "0 of 6" in lines[0] and "run the same command again to resume" in lines[0]


# ---------------------------------------------------------------------- planning times


def test_run_episode_records_the_planners_own_time(monkeypatch) -> None:
    import dataclasses

    from sensorplan.config import load_simulation
    from sensorplan.planners import PLANNERS
    from sensorplan.planners.random_plan import RandomPlanner
    from sensorplan.simulation import run_episode

    @dataclasses.dataclass(frozen=True)
    class SlowStart(RandomPlanner):
        """Sleeps before its own clock starts and reports a fixed own time."""

        name: ClassVar[str] = "slow-start"

        def plan(self, problem, rng=None):
            time.sleep(0.05)
            return dataclasses.replace(super().plan(problem, rng), seconds=0.001)

    monkeypatch.setitem(PLANNERS, "slow-start", SlowStart)
    cfg = load_simulation(ROOT / "configs" / "quick.toml", None,
                          {"steps": 4, "planner": "slow-start"})
    ep = run_episode(cfg.scenario, cfg.settings, 1)
    np.testing.assert_array_equal(ep.planning_seconds, 0.001)

    @dataclasses.dataclass(frozen=True)
    class NoClock(RandomPlanner):
        """Reports no time of its own (a plugin that leaves ``seconds`` at 0)."""

        name: ClassVar[str] = "no-clock"

        def plan(self, problem, rng=None):
            time.sleep(0.02)
            return dataclasses.replace(super().plan(problem, rng), seconds=0.0)

    monkeypatch.setitem(PLANNERS, "no-clock", NoClock)
    cfg = load_simulation(ROOT / "configs" / "quick.toml", None,
                          {"steps": 4, "planner": "no-clock"})
    ep = run_episode(cfg.scenario, cfg.settings, 1)
    assert np.all(ep.planning_seconds >= 0.02)            # the call's wall time instead


# -------------------------------------------------------------------- progress lines


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_the_first_eta_leaves_out_the_start_up() -> None:
    clock, lines = Clock(), []
    p = PlainProgress("study s", "", parallel=2, write=lines.append, clock=clock)
    p(0, 100, 0)
    clock.t = 8.0                 # worker start-up: the first pair arrives after 8 s ...
    p(1, 100, 0, seconds=0.5)     # ... but it computed for 0.5 s
    assert len(lines) == 1 and lines[0].startswith("study s: 1/100 done, 8 s elapsed")
    # 99 pairs of 0.5 s on 2 workers: 24.75 s, not 99 x 8 s.
    assert lines[0].endswith("ETA 25 s")
    for k in range(2, 4):         # then the rate since the first pair, once warm
        clock.t = 8.0 + 0.25 * (k - 1)
        p(k, 100, 0, seconds=0.5)
    clock.t = 8.0 + 0.25 * 10
    p(11, 100, 0, seconds=0.5)
    assert lines[-1] == "study s: 11/100 done, 10 s elapsed, ETA 22 s"


def test_progress_lines_wait_for_work_and_time() -> None:
    clock, lines = Clock(), []
    p = PlainProgress("simulating", "steps", write=lines.append, clock=clock)
    clock.t = FIRST_LINE_SECONDS / 2
    p(5, 10)                       # half done but early: nothing yet
    clock.t = FIRST_LINE_SECONDS / 2 + 0.1
    p(10, 10)                      # done before any line: none at the end either
    assert lines == []
    clock.t, lines2 = 0.0, []
    p = PlainProgress("simulating", "steps", write=lines2.append, clock=clock)
    for done in range(1, 101):
        clock.t = 0.1 * done
        p(done, 100)
    # From 5 s on, every 10 %, and the end.
    assert [ln.split(":")[1].split()[0] for ln in lines2] == \
        ["50/100", "60/100", "70/100", "80/100", "90/100", "100/100"]
    assert "ETA" not in lines2[-1] and lines2[0].startswith("simulating: 50/100 steps done")


def test_simulate_shows_plain_progress_when_not_on_a_terminal(tmp_path, capsys,
                                                              monkeypatch) -> None:
    from sensorplan.cli import console
    monkeypatch.setattr(console, "FIRST_LINE_SECONDS", 0.0)
    code, _, err = run(capsys, "simulate", ROOT / "configs" / "quick.toml", "--steps", "20",
                       "--out", tmp_path / "o")
    assert code == 0, err
    lines = err.splitlines()
    assert lines and all(ln.startswith("simulating: ") for ln in lines)
    assert lines[-1].startswith("simulating: 20/20 steps done")


@pytest.mark.slow
def test_a_real_cluster_losing_every_worker(tmp_path, capsys) -> None:
    import threading

    from distributed import LocalCluster

    f = tmp_path / "s.toml"
    f.write_text(TEXT.replace("runs = 3", "runs = 20").replace("steps = 8", "steps = 30"))
    study = parse_study(f.read_text())
    out = tmp_path / "o"
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    try:
        def kill_every_worker() -> None:
            deadline = time.monotonic() + 120
            while not (out.exists() and studies.done_tasks(out, study)):
                if time.monotonic() > deadline:
                    return
                time.sleep(0.05)
            for nanny in list(cluster.workers.values()):
                os.kill(nanny.process.process.pid, signal.SIGKILL)

        killer = threading.Thread(target=kill_every_worker)
        killer.start()
        code, _, err = run(capsys, "study", f, "--out", out, "--scheduler",
                           cluster.scheduler_address)
        killer.join()
    finally:
        cluster.close()
    assert code == 1, err
    # Progress lines may come first (the cluster took seconds to start); then one line.
    lines = [ln for ln in err.splitlines() if not ln.startswith("study s: ")]
    assert len(lines) == 1 and "the Dask cluster lost the study" in lines[0], err
    assert "run the same command again to resume" in lines[0] and "Traceback" not in err
    res = run(capsys, "study", f, "--out", out, "--workers", "2")      # resumes
    assert res[0] == 0, res[2]
    assert studies.load_study_dir(out).complete


# ------------------------------------------- damaged places that cannot be rewritten


def test_a_directory_in_place_of_a_part_file_is_one_line(reference, tmp_path, capsys
                                                          ) -> None:
    out = _copy(reference, tmp_path / "study")
    for t in ("steps", "decisions", "sensors"):
        (out / f"{t}.parquet").unlink()
    bad = sums_path(out, 1, 0)
    bad.unlink()
    bad.mkdir()                                           # cannot be removed as a file
    study_file = tmp_path / "s.toml"
    study_file.write_text(TEXT)
    line = assert_bad_input(run(capsys, "study", study_file, "--out", out, "--workers", "1"),
                            "--out")
    assert str(bad) in line and "delete it" in line
    bad.rmdir()                                           # as the line says: then resume
    code, stdout, err = run(capsys, "study", study_file, "--out", out, "--workers", "1")
    assert code == 0, err
    assert "ran 1 of 6" in stdout
    assert_same(frames(out), frames(reference))


def test_a_directory_in_place_of_meta_json_is_one_line(reference, tmp_path, capsys) -> None:
    out = _copy(reference, tmp_path / "study")
    (out / "steps.parquet").unlink()                      # so that the study has work to do
    (out / "meta.json").unlink()
    (out / "meta.json").mkdir()
    study_file = tmp_path / "s.toml"
    study_file.write_text(TEXT)
    line = assert_bad_input(run(capsys, "study", study_file, "--out", out, "--workers", "1"),
                            "--out")
    # Named by the file meant, not by the temporary name it is written through.
    assert f"cannot write {out / 'meta.json'}: " in line
