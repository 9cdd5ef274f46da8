"""Quality against time budget: Phi / best Phi found, budgets from 1 ms to 1 s.

    .venv/bin/python benchmarks/bench_anytime.py [--decisions 3] [--out docs/figures/anytime.png]
        [--quick]

For three problem sizes,

* the paper's decision (N = 3, M = 5, K = 3, e = 2; ``paper_problem`` states),
* N = 20, M = 50, K = 10 (e = 1, 2,000 m map; the scale case of ``bench_planning.py``),
* the swarm (``swarm_scenario()``: N = 100, M = 200, K = 5, e = 1, 3,000 m map),

each of ``pg``, ``pg-refine`` and ``sequential-greedy`` plans every decision with
``time_budget`` in 13 log-spaced values from 1 ms to 1 s. A result is scored as its Phi over
the best Phi any run found for that decision (every budget and planner, and ``pg`` and
``sequential-greedy`` without a budget). Prints the median score per planner and budget (and
the median seconds used) and draws the curves into a PNG.

Budgets are wall-clock: the curves depend on the machine and on its load (run it on a quiet
machine); the first complete plan takes what it takes even if the budget is smaller.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from factories import paper_problem
from planner_reference import scale_problem, swarm_problem
from sensorplan.planners import make_planner

PLANNERS = ("pg", "pg-refine", "sequential-greedy")
BUDGETS = np.logspace(-3, 0, 13)


def sizes(n: int) -> dict[str, list]:
    rng = np.random.default_rng(2026)
    return {
        "paper (N = 3, M = 5, K = 3)": [paper_problem(rng, horizon=3) for _ in range(n)],
        "N = 20, M = 50, K = 10": [scale_problem(seed=s) for s in range(n)],
        "swarm (N = 100, M = 200, K = 5)": [swarm_problem(seed=s) for s in range(max(1, n - 1))],
    }


def run(problems: list, quick: bool) -> tuple[dict, dict]:
    """Scores and seconds: ``{planner: (n_budgets, n_problems)}``."""
    budgets = BUDGETS[::3] if quick else BUDGETS
    phi = {p: np.zeros((len(budgets), len(problems))) for p in PLANNERS}
    sec = {p: np.zeros((len(budgets), len(problems))) for p in PLANNERS}
    best = np.zeros(len(problems))
    for d, problem in enumerate(problems):
        for name in ("pg", "sequential-greedy"):              # unbudgeted references
            best[d] = max(best[d], make_planner(name).plan(problem).potential)
        for name in PLANNERS:
            for b, budget in enumerate(budgets):
                r = make_planner(name, time_budget=float(budget)).plan(problem)
                phi[name][b, d], sec[name][b, d] = r.potential, r.seconds
                best[d] = max(best[d], r.potential)
        print(f"  decision {d + 1}/{len(problems)} done", file=sys.stderr, flush=True)
    score = {name: phi[name] / best[None, :] for name in PLANNERS}
    return score, sec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--decisions", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "anytime.png"))
    ap.add_argument("--quick", action="store_true", help="5 budgets, 2 decisions")
    args = ap.parse_args()
    n = 2 if args.quick else args.decisions
    budgets = BUDGETS[::3] if args.quick else BUDGETS
    make_planner("pg").plan(paper_problem(np.random.default_rng(0), horizon=1))  # warm-up
    results = {}
    for label, problems in sizes(n).items():
        print(f"## {label}: median Phi / best found over {len(problems)} decisions "
              "(median seconds used)")
        score, sec = run(problems, args.quick)
        results[label] = score
        print("| budget ms | " + " | ".join(PLANNERS) + " |")
        print("|---|" + "---|" * len(PLANNERS))
        for b, budget in enumerate(budgets):
            cells = [f"{np.median(score[p][b]):.3f} ({statistics.median(sec[p][b]):.3f} s)"
                     for p in PLANNERS]
            print(f"| {1e3 * budget:.1f} | " + " | ".join(cells) + " |")
        print()
    plot(results, budgets, Path(args.out))
    print(f"figure: {args.out}")


def plot(results: dict, budgets: np.ndarray, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(4.2 * len(results), 3.6), sharey=True)
    styles = {"pg": ("C0", "o"), "pg-refine": ("C1", "s"), "sequential-greedy": ("C2", "^")}
    for ax, (label, score) in zip(np.atleast_1d(axes), results.items()):
        for name in PLANNERS:
            color, marker = styles[name]
            med = np.median(score[name], axis=1)
            ax.plot(1e3 * budgets, med, marker=marker, color=color, label=name, ms=4)
            if score[name].shape[1] > 1:
                ax.fill_between(1e3 * budgets, score[name].min(axis=1),
                                score[name].max(axis=1), color=color, alpha=0.12)
        ax.set_xscale("log")
        ax.set_xlabel("time budget (ms)")
        ax.set_title(label, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("Phi / best Phi found")
    np.atleast_1d(axes)[0].legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)


if __name__ == "__main__":
    main()
