"""``sensorplan agents``: a closed-loop episode with one agent per platform."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import assert_bad_input, run
from sensorplan.config.agents import load_agents
from sensorplan.decentral import run_agents
from sensorplan.simulation.scenario import paper_scenario
from sensorplan.simulation.settings import RunSettings
from sensorplan.simulation import Episode
from test_decentral_bus import running, wait_gone

SRC = Path(__file__).resolve().parents[2] / "src"


def test_agents_runs_an_episode_and_reports_the_links(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "agents", "--preset", "paper", "--steps", "4", "--seed", "3",
                         "--p-loss", "0.2", "--rounds", "30", "--out", tmp_path)
    assert code == 0, err
    for name in ("episode.npz", "episode.png", "episode.timing.json", "agents.json"):
        assert (tmp_path / name).is_file(), name
    episode = Episode.load(tmp_path / "episode.npz")
    logs = json.loads((tmp_path / "agents.json").read_text())
    assert logs["decision_steps"] == episode.decision_steps.tolist()
    assert len(logs["decisions"]) == len(episode.decision_steps) == 4
    # The same episode and logs as the library call with the settings written out by hand.
    settings = RunSettings(planner="dec-jsfp", planner_params={"p_loss": 0.2, "rounds": 30},
                           steps=4)
    assert episode.settings == settings
    again, again_logs = run_agents(paper_scenario(), settings, 3)
    np.testing.assert_array_equal(again.estimate, episode.estimate)
    np.testing.assert_array_equal(again.sensor_positions, episode.sensor_positions)
    assert [log.sent for log in again_logs] == [d["sent"] for d in logs["decisions"]]
    # The links line adds up the decisions' logs.
    line = next(ln for ln in out.splitlines() if ln.startswith("links: "))
    counts = {k: sum(d[k] for d in logs["decisions"]) for k in ("sent", "delivered", "lost")}
    assert (f"{counts['sent']} messages sent, {counts['delivered']} delivered, "
            f"{counts['lost']} lost") in line
    assert counts["lost"] > 0 and line.endswith("failed agents: none")
    rounds = [d["rounds"] for d in logs["decisions"]]
    assert f"median {np.median(rounds):g}, max {max(rounds):g}" in line


BAD = [
    (["--planner", "pg"], "--planner"),
    (["--p-loss", "2"], "--p-loss"),
    (["--planner", "dec-independent", "--p-loss", "0.1"], "--p-loss"),
    (["--planner", "dec-sequential", "--rounds", "3"], "--rounds"),
    (["--transport", "pigeon"], "--transport"),
    (["--agent-mode", "gossip"], "--agent-mode"),
    (["--rounds", "0"], "--rounds"),
    (["--comm-range", "-1"], "--comm-range"),
    (["--comm-range", "0"], "--comm-range"),
    (["--delay", "-1"], "--delay"),
    (["--p-loss", "-0.1"], "--p-loss"),
    (["--horizon", "0"], "--horizon"),
]


@pytest.mark.parametrize("args,field", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_agent_options_name_the_option(args: list[str], field: str, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert_bad_input(run(capsys, "agents", "--preset", "paper", *args, "--out", out), field)
    assert not out.exists()


def test_every_agent_option_has_a_bad_value_case() -> None:
    """Every option generated from a planner setting's declaration is refused, naming the
    option, by a case of BAD."""
    from sensorplan.decentral.params import agent_params

    options = {p.cli[0] for _, p in agent_params().values()}
    assert options <= {field for _, field in BAD}


def test_agent_options_help_comes_from_the_declarations(
        capsys: pytest.CaptureFixture[str]) -> None:
    """``agents --help`` shows each link and agent option's range and default as its
    planner setting declares them (sensorplan.decentral.params)."""
    from sensorplan.decentral.params import agent_params

    code, out, _ = run(capsys, "agents", "--help")
    assert code == 0
    text = " ".join(re.sub(r"[│╭╮╰╯─]", " ", out).split())
    for f, p in agent_params().values():
        default = f"{f.default:g}" if isinstance(f.default, float) else str(f.default)
        assert f"{p.cli[0]} {p.metavar} " in text
        rule = f", {p.bounds.text()}" if p.bounds is not None else ""
        assert f"{p.brief}{rule}. [default: {default}]" in text, p.cli[0]
    assert "in [0, 1]. [default: 0]" in text                      # --p-loss, by hand
    assert "> 0 m or inf. [default: inf]" in text                 # --comm-range


def test_the_docs_state_each_declared_range_and_default() -> None:
    """docs/decentral.md lists every decentralized planner's own setting with the rule and
    default its declaration has (a changed declaration fails here until the docs follow)."""
    from sensorplan.decentral.params import GROUPS
    from sensorplan.limits import declared_params

    doc = (SRC.parent / "docs" / "decentral.md").read_text()
    for group in GROUPS:
        for f, p in declared_params(group):
            bullet = re.search(rf"^- `{f.name}` \(([^)]*)\)", doc, re.M)
            assert bullet is not None, f.name
            default = f"{f.default:g}" if isinstance(f.default, float) else str(f.default)
            assert p.rule() in bullet.group(1), (f.name, p.rule(), bullet.group(1))
            assert re.search(rf"default `?{re.escape(default)}`?", bullet.group(1)), f.name


def test_the_file_decides_the_planner_unless_it_is_centralized(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text('[planning]\nplanner = "dec-sequential"\n[planning.planner_params]\n'
                    'p_loss = 0.3\n[[targets]]\n[[sensors]]\n')
    cfg = load_agents(path, agent={"delay": 2, "comm_range": float("inf")})
    assert cfg.settings.planner == "dec-sequential"
    assert dict(cfg.settings.planner_params) == {"p_loss": 0.3, "delay": 2,
                                                 "comm_range": float("inf")}
    path.write_text('[planning]\nplanner = "pg"\n[planning.planner_params]\nalpha = 0.5\n'
                    '[[targets]]\n[[sensors]]\n')
    cfg = load_agents(path)
    assert (cfg.settings.planner, dict(cfg.settings.planner_params)) == ("dec-jsfp",
                                                                         {"alpha": 0.5})


# ------------------------------------------------------- the bus: no process outlives it


def _agents(pid: int) -> list[int]:
    """Process ids of the agent processes whose parent is ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid and "decentral.worker" in cmd:
            found.append(int(entry.name))
    return found


def _start(tmp_path: Path, scenario: tuple[str, ...] = ("--preset", "paper", "--steps", "6"),
           n_agents: int = 3) -> tuple[subprocess.Popen[str], list[int]]:
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen([sys.executable, "-m", "sensorplan", "agents", *scenario,
                             "--transport", "bus", "--out", str(tmp_path)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    pids: list[int] = []
    while time.monotonic() < deadline and proc.poll() is None and len(pids) < n_agents:
        pids = _agents(proc.pid)
        time.sleep(0.02)
    assert len(pids) == n_agents, proc.communicate()
    return proc, pids


@pytest.mark.slow
def test_every_agent_process_ends_with_the_run(tmp_path: Path) -> None:
    proc, pids = _start(tmp_path)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert re.search(r"links: 6 decisions, \d+ messages sent", out)
    assert wait_gone(pids) == []


@pytest.mark.slow
@pytest.mark.parametrize("sig,code,line", [(signal.SIGTERM, 143, "error: terminated"),
                                           (signal.SIGINT, 130, "error: interrupted")],
                         ids=["SIGTERM", "SIGINT"])
def test_every_agent_process_ends_when_the_run_is_stopped(tmp_path: Path, sig: int,
                                                           code: int, line: str) -> None:
    proc, pids = _start(tmp_path)
    assert all(running(p) for p in pids)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert err.splitlines() == [line]
    assert wait_gone(pids) == []


SEARCHING = """
look_detects = "all"
births = "edges"
birth_rate = 0.05
initial_targets = 0

[planning]
planner = "dec-jsfp"
horizon = 2
search = "on"
search_sectors = 6

[tracker]
kind = "pmb"

[run]
steps = 3
seed = 2

[[targets]]
kind = "cv"

[[sensors]]
altitude = 490.0
position = [150.0, 150.0]
heading = 0.78

[[sensors]]
altitude = 510.0
position = [450.0, 450.0]
heading = -2.35
"""


@pytest.mark.slow
def test_agents_search_on_the_bus_end_to_end(tmp_path: Path) -> None:
    """A searching episode with one agent process per platform: it searches, it is the
    in-process run's episode, and every agent process ends with it."""
    path = tmp_path / "searching.toml"
    path.write_text(SEARCHING)
    proc, pids = _start(tmp_path / "out", (str(path),), n_agents=2)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert re.search(r"links: 3 decisions, \d+ messages sent", out)
    assert wait_gone(pids) == []
    episode = Episode.load(tmp_path / "out" / "episode.npz")
    assert (episode.searched >= 0).any()
    cfg = load_agents(path)
    inproc, logs = run_agents(cfg.scenario, cfg.settings, cfg.seed)
    for name in ("truth", "sensor_positions", "sensor_headings", "searched", "search_found"):
        np.testing.assert_array_equal(getattr(episode, name), getattr(inproc, name))
    saved = json.loads((tmp_path / "out" / "agents.json").read_text())["decisions"]
    assert [d["sent"] for d in saved] == [log.sent for log in logs]
