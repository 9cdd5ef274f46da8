"""Message-bus overhead: one round of three agent processes, beyond their planning work.

Runs decisions of the paper preset (3 platforms, 5 targets, K = 3, e = 2) with decentralized
JSFP and perfect links, once on the bus (one process per agent, ZeroMQ over ``ipc://``) and
once in-process, and prints medians over every round of every decision:

- ``round``: wall time of a round as the slowest agent saw it (compute, send, wait for the
  peers' messages, apply them);
- ``work``: that agent's own planning work in the round (best response, belief updates);
- ``overhead``: per round, the smallest (round - work) over the three agents. The agent that
  finishes its work last waits for nobody's work, so its excess is messaging alone:
  encoding, sending, waking up, receiving, decoding and the link model;
- ``round - work``: the same for the slowest agent: an upper bound, since it also counts
  time spent waiting for the other agents' work (three processes share this machine's cores);
- ``ratio``: bus decision time / in-process decision time, same decisions, same plans.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_agents.py [--decisions 20]
        [--horizon 3] [--seed 0]

Target: overhead <= 5 ms per round on this machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from factories import paper_problem
from sensorplan.decentral import AgentSpec, LinkModel, decision_key, run_inproc
from sensorplan.decentral.bus import Bus
from sensorplan.planners.information import prepare


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--decisions", type=int, default=20)
    ap.add_argument("--horizon", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    problems = [paper_problem(rng, horizon=args.horizon) for _ in range(args.decisions)]
    spec = AgentSpec("jsfp")
    rounds, works, overheads, excess, ratios, n_rounds = [], [], [], [], [], []
    with Bus(3) as bus:
        bus.decide(problems[0], spec, LinkModel((0,), np.array(problems[0].positions)),
                   np.random.default_rng(0))                                 # warm-up
        for d, problem in enumerate(problems):
            ctx = prepare(problem)
            gen = np.random.default_rng(d)
            link = LinkModel(decision_key(gen), np.array(problem.positions))
            t0 = time.perf_counter()
            ref = run_inproc(ctx, spec, link, gen)
            t1 = time.perf_counter()
            got, failed = bus.decide(problem, spec, link, gen)
            t2 = time.perf_counter()
            assert not failed and all(np.array_equal(got[i].tgt, ref[i].tgt) for i in ref)
            ratios.append((t2 - t1) / (t1 - t0))
            R = got[0].rounds
            n_rounds.append(R)
            for r in range(R):
                rs = np.array([got[i].round_seconds[r] for i in range(3)])
                ws = np.array([got[i].work_seconds[r] for i in range(3)])
                slowest = int(np.argmax(rs))
                rounds.append(rs[slowest])
                works.append(ws[slowest])
                overheads.append(float(np.min(rs - ws)))
                excess.append(rs[slowest] - ws[slowest])

    ms = 1e3
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}")
    print(f"{len(problems)} decisions, {sum(n_rounds)} rounds "
          f"(median {statistics.median(n_rounds):.0f} per decision), 3 agent processes")
    print(f"median round     {statistics.median(rounds) * ms:7.3f} ms")
    print(f"median work      {statistics.median(works) * ms:7.3f} ms")
    print(f"median overhead  {statistics.median(overheads) * ms:7.3f} ms   "
          f"(95th percentile {np.percentile(overheads, 95) * ms:.3f} ms; target <= 5 ms)")
    print(f"median round - work of the slowest agent  {statistics.median(excess) * ms:.3f} ms "
          f"(95th percentile {np.percentile(excess, 95) * ms:.3f} ms)")
    print(f"median ratio bus / in-process decision time  {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
