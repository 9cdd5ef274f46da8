"""What a look detects: its own target only, or every live target in its sensing region."""

from __future__ import annotations

import numpy as np
import pytest

from sensorplan.models import radar
from sensorplan.models.sensors import SensorParams, radar_table
from sensorplan.simulation import run_streams
from sensorplan.simulation.sensing import Sensing

STEPS = 5


def scene(rng: np.random.Generator, M: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    truth = np.zeros((M, 4))
    truth[:, :2] = rng.uniform(0.0, 600.0, (M, 2))
    positions = np.array([[100.0, 100.0], [500.0, 300.0], [300.0, 550.0]])
    headings = np.array([0.8, 2.8, -1.6])
    return truth, positions, headings


def test_a_look_detects_every_live_target_in_its_region_with_ideal_sensors() -> None:
    table = radar_table((SensorParams(),) * 3)
    rng = np.random.default_rng(11)
    truth, pos, head = scene(rng)
    s = Sensing(table, np.zeros((0, 5)), run_streams(3), STEPS, look_detects="all")
    aimed = np.array([0, -1, 5])
    looks, sensed = s.look(1, truth, pos, head, aimed)
    # every sensor looks along its heading, aimed at a track or not
    np.testing.assert_array_equal(looks.sensors, [0, 1, 2])
    np.testing.assert_array_equal(looks.aims, [0, -1, 5])
    for n, i in enumerate(looks.sensors):
        h, _, var, seen = radar.measure_looks(table, np.full(len(truth), i), truth[:, :2],
                                              np.repeat(pos[i:i + 1], len(truth), 0),
                                              np.full(len(truth), head[i]))
        assert len(looks.detections[n]) == seen.sum()
        np.testing.assert_array_equal(np.flatnonzero(sensed.measured[:, i]), np.flatnonzero(seen))
        # each detection is its target's measurement plus noise (within 6 sigma)
        dz = looks.detections[n] - h[seen]
        dz[:, 1] = np.angle(np.exp(1j * dz[:, 1]))
        assert np.all(np.abs(dz) < 6 * np.sqrt(var[seen]))
    assert not sensed.missed[1]                             # no target to miss


def test_a_targets_detections_do_not_depend_on_the_others() -> None:
    table = radar_table((SensorParams(detection="swerling1", false_alarm_probability=1e-6),) * 3)
    truth, pos, head = scene(np.random.default_rng(5))
    aimed = np.array([0, 1, 2])
    a = Sensing(table, np.zeros((0, 5)), run_streams(8), STEPS, look_detects="all")
    b = Sensing(table, np.zeros((0, 5)), run_streams(8), STEPS, look_detects="all")
    alive = np.ones(len(truth), dtype=bool)
    _, sa = a.look(2, truth, pos, head, aimed, alive)
    alive[1::2] = False                                     # half of them gone
    _, sb = b.look(2, truth, pos, head, aimed, alive)
    np.testing.assert_array_equal(sb.measured[::2], sa.measured[::2])
    assert not sb.measured[1::2].any()


@pytest.mark.parametrize("rate", [0.0, 4.0])
def test_false_alarms_follow_the_targets_detections(rate: float) -> None:
    table = radar_table((SensorParams(clutter_rate=rate),) * 3)
    truth, pos, head = scene(np.random.default_rng(2))
    s = Sensing(table, np.zeros((0, 5)), run_streams(1), STEPS, look_detects="all")
    aimed = np.array([0, 1, 2])
    looks, sensed = s.look(3, truth, pos, head, aimed)
    for n, i in enumerate(looks.sensors):
        assert len(looks.detections[n]) == sensed.measured[:, i].sum() + sensed.false_alarms[i]
    if rate == 0.0:
        assert not sensed.false_alarms.any()


def test_an_unknown_look_detects_is_refused() -> None:
    with pytest.raises(ValueError, match="look_detects"):
        Sensing(radar_table((SensorParams(),)), np.zeros((0, 5)), run_streams(1), 2,
                look_detects="some")


def test_a_multi_target_trackers_aims_are_tracks_not_targets() -> None:
    # A multi-target tracker can report more tracks than there are targets (a track started
    # from a false alarm): an aim at track 12 of 12 targets must not be read as a target.
    table = radar_table((SensorParams(clutter_rate=2.0),) * 3)
    truth, pos, head = scene(np.random.default_rng(4))
    tracks = Sensing(table, np.zeros((0, 5)), run_streams(6), STEPS, look_detects="all",
                     aims_at_targets=False)
    targets = Sensing(table, np.zeros((0, 5)), run_streams(6), STEPS, look_detects="all")
    looks, sensed = tracks.look(2, truth, pos, head, np.array([12, 0, -1]))
    ref_looks, ref = targets.look(2, truth, pos, head, np.array([-1, -1, -1]))
    np.testing.assert_array_equal(looks.aims, [12, 0, -1])     # the tracker gets its aims
    assert not sensed.missed.any() and not sensed.seen.any()   # no look has a target to miss
    np.testing.assert_array_equal(sensed.measured, ref.measured)
    np.testing.assert_array_equal(sensed.false_alarms, ref.false_alarms)
    for a, b in zip(looks.detections, ref_looks.detections, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("height", [300.0, 1500.0, 9000.0])
def test_a_recorded_height_sets_the_noise_but_not_the_mean(height: float) -> None:
    """With each target's height given, a look's noise is the radar model's at the true
    slant range and elevation (sigma_r ~ r^2, sigma_phi ~ r^2 / cos psi), while the
    measurement's mean stays the model's at the table's altitude: the same noise draw,
    scaled by the closed-form ratio."""
    z, dep = 1500.0, 0.3
    table = radar_table((SensorParams(altitude=z, depression=dep, min_ground_range=100.0,
                                      max_ground_range=30000.0),))
    g, a = 12000.0, 0.2
    truth = np.array([[g * np.cos(a), g * np.sin(a), 0.0, 0.0]])
    pos, head, aimed = np.zeros((1, 2)), np.zeros(1), np.array([-1])
    plain = Sensing(table, np.zeros((0, 5)), run_streams(4), STEPS, look_detects="all")
    tall = Sensing(table, np.zeros((0, 5)), run_streams(4), STEPS, look_detects="all")
    z_plain = plain.look(1, truth, pos, head, aimed)[0].detections[0]
    z_tall = tall.look(1, truth, pos, head, aimed, heights=np.array([height]))[0].detections[0]
    mean = np.array([np.hypot(g, z), a])
    r_n, r_t = np.hypot(g, z), np.hypot(g, height)
    cos_n = (np.cos(dep) * g * np.cos(a) + np.sin(dep) * z) / r_n
    cos_t = (np.cos(dep) * g * np.cos(a) + np.sin(dep) * height) / r_t
    ratio = np.array([(r_t / r_n) ** 2, (r_t**2 / cos_t) / (r_n**2 / cos_n)])
    np.testing.assert_allclose((z_tall - mean)[0], ratio * (z_plain - mean)[0], rtol=1e-9)
