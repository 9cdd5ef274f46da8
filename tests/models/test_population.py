"""Targets that are born and die: birth rate, edge and uniform births, survival, slots, the
streams, and the known-target truth kept bit for bit."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from sensorplan.models.population import (PopulationTruth, edge_births, outside_map,
                                          uniform_births)
from sensorplan.models.truth import NOISE_BLOCK, TruthModel, inside_buildings
from sensorplan.simulation.run import run_streams
from sensorplan.models.scripted import scripted_truth
from sensorplan.simulation.scenario import (PRESETS, SensorSpec, benchmark_scenario,
                                            draw_initial, make_population, make_truth,
                                            search_scenario)

DATA = Path(__file__).resolve().parents[1] / "data"
KINDS = ("cv", "cv", "cv", "dubins", "dubins")


def population(births, rate=0.0, survival=1.0, x0=None, size=(300.0, 200.0), seed=1,
               buildings=None, q=0.05, speed=(3.0, 6.0), kinds=KINDS):
    T = len(kinds)
    x0 = np.zeros((0, 4)) if x0 is None else x0
    return PopulationTruth(kinds, x0, np.random.default_rng(seed),
                           np.random.default_rng(seed + 1000), turn_hold=np.full(T, 10.0),
                           max_turn_rate=np.full(T, 0.1), world_size=size, dt=1.0,
                           process_noise=q, births=births, birth_rate=rate,
                           survival_probability=survival, speed_range=speed,
                           buildings=buildings)


def run(pop, steps):
    """Step ``pop``; return every step's (states, alive)."""
    return [pop.step() for _ in range(steps)]


def digest(*arrays):
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


# ------------------------------------------------------------------ known targets, unchanged

@pytest.mark.parametrize("through", ["make_truth", "make_population"])
@pytest.mark.parametrize("key", sorted(json.loads((DATA / "truth_golden.json").read_text())))
def test_presets_draw_what_main_drew(key, through):
    """The presets' initial conditions and trajectories, through make_truth and through a
    population without births or deaths, hash as main's code drew them before births
    existed (tests/data/truth_golden.json); the population never draws from its births
    stream."""
    golden = json.loads((DATA / "truth_golden.json").read_text())[key]
    name, seed = key.rsplit("_", 1)
    sc = PRESETS[name]()
    streams = run_streams(int(seed))
    truth_rng = np.random.default_rng(streams["truth"])
    init = draw_initial(sc, truth_rng, np.random.default_rng(streams["init"]))
    assert digest(init.truth, init.estimate, init.positions, init.headings) == \
        golden["initial"]
    traj = [init.truth]
    if through == "make_truth":
        model = make_truth(sc, init.truth, truth_rng)
        traj += [model.step() for _ in range(golden["steps"])]
    else:
        births_rng = np.random.default_rng(99)
        before = births_rng.bit_generator.state
        pop = make_population(sc, init.truth, truth_rng, births_rng)
        for _ in range(golden["steps"]):
            x, alive = pop.step()
            assert alive.all()
            traj.append(x)
        assert births_rng.bit_generator.state == before
    assert digest(np.array(traj)) == golden["truth"]


# ------------------------------------------------------------------------- birth rate

@pytest.mark.parametrize("births, survival", [("edges", 1.0), ("uniform", 0.8)])
def test_births_per_step_are_poisson_with_the_rate(births, survival):
    """Total births over S steps is Poisson(rate S): within 4 standard deviations; the
    per-step counts have variance equal to their mean (dispersion index within its
    chi-square 99.9 % interval)."""
    rate, S = 0.7, 3000
    pop = population(births, rate, survival, size=(100.0, 80.0), seed=5)
    run(pop, S)
    counts = np.bincount(pop.birth_step, minlength=S + 1)[1:]
    assert abs(counts.sum() - rate * S) <= 4 * math.sqrt(rate * S)
    dispersion = (S - 1) * counts.var(ddof=1) / counts.mean()
    assert stats.chi2.ppf(0.0005, S - 1) <= dispersion <= stats.chi2.ppf(0.9995, S - 1)


def test_no_births_with_rate_zero_or_births_none():
    for births, rate in (("edges", 0.0), ("none", 0.0)):
        x0 = np.array([[150.0, 100.0, 1.0, 0.0]])
        pop = population(births, rate, x0=x0)
        run(pop, 50)
        assert len(pop.states) == 1


# ------------------------------------------------------------------------ edge births

def test_edge_births_start_on_the_boundary_heading_inward():
    """Every target born at the edges is on the boundary at its birth step with a velocity
    pointing into the map; sides are hit in proportion to their length and the angle to the
    inward normal is uniform on (-pi/2, pi/2) (Kolmogorov-Smirnov at 1e-3)."""
    W, H = 300.0, 100.0
    pop = population("edges", 2.0, size=(W, H), seed=3)
    born_states = []
    for t in range(1, 1001):
        x, _ = pop.step()
        born_states.append(x[pop.birth_step == t])
    b = np.concatenate(born_states)
    assert len(b) > 1500
    side = np.select([b[:, 1] == 0.0, b[:, 0] == W, b[:, 1] == H, b[:, 0] == 0.0],
                     [0, 1, 2, 3], -1)
    assert np.all(side >= 0)
    normal = np.array([[0, 1], [-1, 0], [0, -1], [1, 0]], float)[side]
    inward = np.sum(b[:, 2:] * normal, axis=1)
    assert np.all(inward > 0)
    speed = np.hypot(b[:, 2], b[:, 3])
    assert speed.min() >= 3.0 and speed.max() <= 6.0
    angle = np.arctan2(normal[:, 0] * b[:, 3] - normal[:, 1] * b[:, 2], inward)
    assert stats.kstest(angle, stats.uniform(-np.pi / 2, np.pi).cdf).pvalue > 1e-3
    share = np.bincount(side, minlength=4) / len(b)
    expected = np.array([W, H, W, H]) / (2 * (W + H))
    chi2 = len(b) * np.sum((share - expected) ** 2 / expected)
    assert chi2 < stats.chi2.ppf(0.999, 3)


def test_edge_births_helper_walks_the_perimeter():
    # A fixed generator: each coordinate lands on the side its perimeter length says.
    class Fixed:
        def __init__(self, values):
            self.values = list(values)

        def uniform(self, lo, hi, n):
            return np.array(self.values.pop(0), dtype=float)

    s = [10.0, 350.0, 450.0, 790.0]        # W = 300, H = 100: bottom, right, top, left
    x = edge_births(4, Fixed([s, [4.0] * 4, [0.0] * 4]), (300.0, 100.0), (3.0, 6.0))
    np.testing.assert_allclose(x[:, :2], [[10, 0], [300, 50], [250, 100], [0, 10]], atol=1e-12)
    np.testing.assert_allclose(x[:, 2:], [[0, 4], [-4, 0], [0, -4], [4, 0]], atol=1e-12)


def test_a_target_that_leaves_the_map_dies_and_keeps_its_last_state():
    W, H = 200.0, 150.0
    pop = population("edges", 0.3, size=(W, H), seed=11)
    prev_states = pop.states
    for t in range(1, 601):
        was_alive = pop.alive.copy()
        x, alive = pop.step()
        n = len(was_alive)
        died = was_alive & ~alive[:n]
        assert np.all(pop.death_step[:n][died] == t)
        # A dead slot keeps its last live state; the live ones are inside the map.
        np.testing.assert_array_equal(x[:n][died], prev_states[died])
        assert not outside_map(x[alive, :2], (W, H)).any()
        prev_states = x
    assert np.sum(pop.death_step > 0) > 50


def test_with_edges_the_initial_targets_move_as_known_targets_until_they_leave():
    """Births come from a stream of their own: on a map they cannot leave in the run, the
    initial targets' trajectories equal the known-target model's bit for bit."""
    rng = np.random.default_rng(8)
    x0 = np.column_stack([rng.uniform(4e5, 6e5, (5, 2)), rng.uniform(-6, 6, (5, 2))])
    size = (1e6, 1e6)
    pop = population("edges", 0.5, x0=x0, size=size, seed=21)
    ref = TruthModel(KINDS, x0, np.random.default_rng(21), turn_hold=np.full(5, 10.0),
                     max_turn_rate=np.full(5, 0.1), world_size=size, dt=1.0,
                     process_noise=0.05)
    for _ in range(NOISE_BLOCK + 20):
        x, alive = pop.step()
        np.testing.assert_array_equal(x[:5], ref.step())
    assert len(x) > 5 and alive[:5].all()


# --------------------------------------------------------------------- uniform births

def test_uniform_births_never_inside_a_building():
    """Births and every later position stay out of the buildings (a third of the map)."""
    blds = np.array([[20.0, 20.0, 80.0, 80.0, 30.0], [120.0, 10.0, 190.0, 60.0, 30.0],
                     [100.0, 90.0, 180.0, 140.0, 30.0]])
    pop = population("uniform", 1.5, survival=0.95, size=(200.0, 150.0), buildings=blds,
                     seed=4)
    for _ in range(400):
        x, alive = pop.step()
        assert not inside_buildings(x[alive, :2], blds).any()
        assert not outside_map(x[alive, :2], (200.0, 150.0)).any()
    assert len(pop.states) > 450


def test_uniform_births_are_uniform_outside_the_buildings():
    # One building over the left half of the lower half: births in the three free
    # quarters, each a third (chi-square at 1e-3); x uniform in the upper half (KS).
    blds = np.array([[0.0, 0.0, 100.0, 50.0, 10.0]])
    x = uniform_births(6000, np.random.default_rng(2), (200.0, 100.0), (3.0, 6.0), blds)
    assert not inside_buildings(x[:, :2], blds).any()
    quarter = (x[:, 0] >= 100).astype(int) + 2 * (x[:, 1] >= 50)
    counts = np.bincount(quarter, minlength=4)
    assert counts[0] == 0
    assert stats.chisquare(counts[1:]).pvalue > 1e-3
    upper = x[x[:, 1] >= 50, 0]
    assert stats.kstest(upper, stats.uniform(0, 200).cdf).pvalue > 1e-3
    heading = np.arctan2(x[:, 3], x[:, 2])
    assert stats.kstest(heading, stats.uniform(-np.pi, 2 * np.pi).cdf).pvalue > 1e-3


# --------------------------------------------------------------------------- survival

@pytest.mark.parametrize("p", [0.9, 0.97])
def test_lifetimes_are_geometric(p):
    """With uniform births, a target born at step b dies at b + L with L geometric on
    {1, 2, ...}, mean 1 / (1 - p), variance p / (1 - p)^2: the mean lifetime of the
    targets born in the first half is within 4 standard errors, and so is the share dying
    at the first step after their birth, 1 - p; none dies at its birth step."""
    S = 4000
    pop = population("uniform", 2.0, survival=p, size=(300.0, 300.0), seed=7)
    run(pop, S)
    first = pop.birth_step <= S // 2
    assert np.all(pop.death_step[first] > 0)   # P(a life > S/2) is below 1e-26
    life = (pop.death_step - pop.birth_step)[first]
    n = len(life)
    mean, var = 1 / (1 - p), p / (1 - p) ** 2
    assert abs(life.mean() - mean) <= 4 * math.sqrt(var / n)
    assert life.min() >= 1
    assert abs(np.mean(life == 1) - (1 - p)) <= 4 * math.sqrt(p * (1 - p) / n)


def test_survival_of_known_targets():
    """Without births the initial targets die one by one: the number alive after t steps
    is binomial(M, p^t)."""
    M, p, t = 2000, 0.95, 20
    rng = np.random.default_rng(0)
    x0 = np.column_stack([rng.uniform(0, 300, M), rng.uniform(0, 200, M),
                          np.zeros(M), np.zeros(M)])
    pop = population("none", survival=p, x0=x0, seed=9, kinds=("cv",))
    for _ in range(t):
        _, alive = pop.step()
    expected = M * p**t
    assert abs(alive.sum() - expected) <= 4 * math.sqrt(M * p**t * (1 - p**t))


# ------------------------------------------------------------------------------ slots

def test_slots_are_never_reused():
    """A slot is born once, at a step that never decreases with its index; once dead it
    stays dead with its death step, birth step and last state unchanged."""
    pop = population("uniform", 1.0, survival=0.9, size=(100.0, 100.0), seed=13)
    seen_dead: dict[int, tuple[int, int, np.ndarray]] = {}
    n_prev = 0
    for t in range(1, 301):
        x, alive = pop.step()
        assert len(x) == len(alive) == len(pop.birth_step) == len(pop.death_step) >= n_prev
        assert np.all(pop.birth_step[n_prev:] == t)
        assert np.all(np.diff(pop.birth_step) >= 0)
        np.testing.assert_array_equal(alive, pop.death_step == -1)
        for s, (b, d, state) in seen_dead.items():
            assert not alive[s] and pop.birth_step[s] == b and pop.death_step[s] == d
            np.testing.assert_array_equal(x[s], state)
        for s in np.flatnonzero(~alive):
            seen_dead.setdefault(int(s), (int(pop.birth_step[s]), int(pop.death_step[s]),
                                          x[s].copy()))
        n_prev = len(x)
    assert len(seen_dead) > 100


def test_born_targets_take_the_templates_in_turn():
    kinds = ("cv", "dubins", "dubins")
    x0 = np.array([[50.0, 50.0, 1.0, 0.0]])
    pop = population("uniform", 2.0, survival=0.9, x0=x0, size=(100.0, 100.0), kinds=kinds)
    run(pop, 30)
    slots = np.arange(len(pop.kinds))
    np.testing.assert_array_equal(pop.kinds, np.array(kinds)[slots % 3])
    assert len(slots) > 20


def test_same_seeds_same_population():
    a = population("uniform", 1.0, survival=0.9, seed=2)
    b = population("uniform", 1.0, survival=0.9, seed=2)
    for (xa, la), (xb, lb) in zip(run(a, 100), run(b, 100), strict=True):
        np.testing.assert_array_equal(xa, xb)
        np.testing.assert_array_equal(la, lb)


def test_bad_arguments():
    with pytest.raises(ValueError, match="births"):
        population("everywhere")
    with pytest.raises(ValueError, match="birth_rate"):
        population("edges", -0.1)
    with pytest.raises(ValueError, match="survival_probability"):
        population("edges", survival=0.0)
    with pytest.raises(ValueError, match="grows without bound"):
        population("uniform", 1.0)


# ---------------------------------------------------------------------- the scenarios

def test_search_scenario_keeps_three_to_eight_targets_alive_most_of_the_time():
    """The search truth's purpose, on seeds other than the development ones its birth rate
    was chosen on: 3 to 8 targets alive in at least 75 % of the steps of 200-step runs
    (87 % on the development seeds), and births on every run."""
    sc = search_scenario()
    assert (sc.births, sc.n_initial, sc.survival_probability) == ("edges", 3, 1.0)
    share, born = [], []
    for seed in range(20):
        streams = run_streams(seed)
        truth_rng = np.random.default_rng(streams["truth"])
        init = draw_initial(sc, truth_rng, np.random.default_rng(streams["init"]))
        assert init.truth.shape == (3, 4)
        pop = make_population(sc, init.truth, truth_rng, np.random.default_rng(seed + 5))
        counts = [pop.step()[1].sum() for _ in range(200)]
        share.append(np.mean([3 <= c <= 8 for c in counts]))
        born.append(len(pop.states) - 3)
    assert np.mean(share) >= 0.75
    assert min(born) > 0


def test_a_scripted_scenario_is_its_benchmark_s_truth():
    sc = benchmark_scenario("vo12", (SensorSpec(),))
    pop = make_population(sc, np.zeros((0, 4)), np.random.default_rng(0),
                          np.random.default_rng(1))
    ref = scripted_truth("vo12")
    for _ in range(100):
        (x, a), (y, b) = pop.step(), ref.step()
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="make_population"):
        make_truth(sc, np.zeros((0, 4)), np.random.default_rng(0))
