"""Where the recorded traffic's aircraft begin and end: the rates a tracker's births and
survival take from the truth.

Counts the aircraft-steps of the preset's window, the aircraft present at the start, those
born later, and the ends: at the map's edge (the last position within ``--margin`` of it:
the aircraft flew out, which a tracker's map edge charges) or inside (landings, which only
its survival probability can explain). The births per step and the survival per step
``1 - ends inside / aircraft-steps`` follow.

    python scripts/traffic_lives.py [--margin 2000]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from sensorplan.models.traffic import TRAFFIC, load_flights


@dataclass(frozen=True)
class Lives:
    """The counts (module docstring)."""

    aircraft_steps: int
    at_start: int
    born: int
    ends_at_edge: int
    ends_inside: int
    steps: int

    @property
    def birth_rate(self) -> float:
        """Births per step after the first."""
        return self.born / (self.steps - 1)

    @property
    def survival(self) -> float:
        """Probability that an aircraft on the map does not end inside it in a step."""
        return 1.0 - self.ends_inside / self.aircraft_steps


def lives(states: np.ndarray, birth_step: np.ndarray, death_step: np.ndarray, side: float,
          margin: float) -> Lives:
    """The counts for ``states (S + 1, M, 4)`` (NaN outside a life) on a square map of
    ``side`` m; ``birth_step`` the first step alive, ``death_step`` the first step absent
    (-1: alive to the end)."""
    live = np.isfinite(states[..., 0])
    ended = np.flatnonzero(death_step >= 0)
    last = states[death_step[ended] - 1, ended, :2]
    to_edge = np.minimum(last, side - last).min(axis=1)
    inside = int(np.count_nonzero(to_edge > margin))
    first = int(birth_step.min())
    return Lives(int(live.sum()), int(np.count_nonzero(birth_step == first)),
                 int(np.count_nonzero(birth_step > first)), len(ended) - inside, inside,
                 states.shape[0] - first)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--margin", type=float, default=2000.0,
                    help="an end this close to the edge (m) is an exit (default: a 2 km cell)")
    a = ap.parse_args(argv)
    f = load_flights()
    n = lives(f.states, f.birth_step, f.death_step, TRAFFIC.side, a.margin)
    print(f"{n.aircraft_steps} aircraft-steps over {n.steps} steps; {n.at_start} aircraft at "
          f"the start, {n.born} born later ({n.birth_rate:.3f} a step)")
    print(f"ends: {n.ends_at_edge} at the edge (last position within {a.margin:g} m of it), "
          f"{n.ends_inside} inside; survival per step {n.survival:.5f}")


if __name__ == "__main__":
    main()
