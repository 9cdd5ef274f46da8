"""The recorded-traffic truth: the projection, the resampling, lives on the map, the pinned
records and the error when they are missing. Nothing here downloads: the one test on the real
records is skipped when they have not been fetched."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sensorplan.errors import ConfigError
from sensorplan.models import traffic as tf

REF = (48.8665, 2.46365)
R = tf.EARTH_RADIUS
#: Metres per degree of latitude, and of longitude at the reference latitude.
M_LAT = R * math.pi / 180
M_LON = M_LAT * math.cos(math.radians(REF[0]))


def records(tracks: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
            ) -> pd.DataFrame:
    """A records frame (:func:`~sensorplan.models.traffic.read_records`'s columns) from
    ``{icao24: (t, east, north, altitude)}`` in the local frame about ``REF``."""
    rows = []
    for name, (t, e, n, h) in tracks.items():
        rows.append(pd.DataFrame({"t": t, "icao24": name, "latitude": REF[0] + n / M_LAT,
                                  "longitude": REF[1] + e / M_LON, "altitude": h}))
    return pd.concat(rows, ignore_index=True)


def test_the_projection_is_the_equirectangular_one():
    e, n = tf.project(np.array([REF[0], REF[0] + 1.0, REF[0]]),
                      np.array([REF[1], REF[1], REF[1] - 0.5]), REF)
    np.testing.assert_allclose(e, [0.0, 0.0, -0.5 * M_LON], atol=1e-6)
    np.testing.assert_allclose(n, [0.0, M_LAT, 0.0], atol=1e-6)
    # One degree of latitude is 111.195 km on the mean sphere.
    assert abs(M_LAT - 111195.0) < 1.0


def test_a_straight_flight_is_resampled_exactly():
    area = tf.TrafficArea(reference=REF, side=20000.0, start=1000.0, dt=5.0, steps=40)
    t = np.arange(990.0, 1300.0, 1.0)                      # records every second
    v = np.array([120.0, -35.0])                          # m/s east, north
    p0 = np.array([-8000.0, 3000.0])                      # east, north at t = 990
    e, n = p0[0] + v[0] * (t - 990), p0[1] + v[1] * (t - 990)
    h = 3000.0 - 4.0 * (t - 990)
    f = tf.trajectories(records({"abc123": (t, e, n, h)}), area)
    assert f.names == ("abc123",) and f.states.shape == (41, 1, 4)
    # Inside the map from t = 990 (x = 2000 m) until it leaves across the east edge (east =
    # +10 km) at t = 990 + 18000 / 120 = 1140 s: alive from step 1 to step 28 (1140 s).
    t_out = 990 + 18000 / 120
    assert f.birth_step[0] == 1 and f.death_step[0] == math.floor((t_out - 1000) / 5) + 1
    k = np.arange(f.birth_step[0], f.death_step[0])
    tk = 1000.0 + 5.0 * k
    want = np.stack([p0[0] + v[0] * (tk - 990) + 10000, p0[1] + v[1] * (tk - 990) + 10000,
                     np.full(len(k), v[0]), np.full(len(k), v[1])], axis=1)
    # Interpolation is exact on a straight line (up to the projection's round trip).
    np.testing.assert_allclose(f.states[k, 0], want, rtol=0, atol=1e-6)
    np.testing.assert_allclose(f.heights[k, 0], 3000.0 - 4.0 * (tk - 990), atol=1e-6)
    assert np.isnan(f.states[0, 0]).all() and np.isnan(f.states[f.death_step[0]:, 0]).all()


def test_targets_enter_and_leave_when_their_records_are_on_the_map():
    area = tf.TrafficArea(reference=REF, side=20000.0, start=0.0, dt=5.0, steps=100)
    t = np.arange(0.0, 501.0, 1.0)
    # Enters across the west edge (east = -10 km) at t = 123.4 s, still inside at the end.
    enter = records({"a": (t, -10000 + 30.0 * (t - 123.4), 0 * t, 1000 + 0 * t)})
    # Recorded from t = 52.5 s to t = 260 s, inside the whole time (a take-off and a
    # landing): alive from step 11 (55 s) to step 52 (260 s).
    hop = records({"b": (np.arange(52.5, 260.5, 0.5), 0 * np.arange(52.5, 260.5, 0.5),
                         0 * np.arange(52.5, 260.5, 0.5), 500 + 0 * np.arange(52.5, 260.5,
                                                                               0.5))})
    f = tf.trajectories(pd.concat([enter, hop], ignore_index=True), area)
    assert f.names == ("b", "a")                           # in the order of their births
    assert list(f.birth_step) == [11, math.ceil(123.4 / 5)]
    assert list(f.death_step) == [53, -1]
    alive = np.isfinite(f.states[..., 0])
    assert alive[11:53, 0].all() and not alive[:11, 0].any() and not alive[53:, 0].any()


def test_a_gap_in_the_records_makes_two_targets():
    area = tf.TrafficArea(reference=REF, side=20000.0, start=0.0, dt=5.0, steps=100)
    t = np.r_[np.arange(0.0, 100.0), np.arange(300.0, 400.0)]    # 200 s without records
    f = tf.trajectories(records({"c": (t, 0 * t, 0 * t, 800 + 0 * t)}), area)
    assert f.names == ("c", "c")
    assert list(f.birth_step) == [1, 60] and list(f.death_step) == [20, 80]


def test_the_truth_replays_the_flights_with_their_heights():
    area = tf.TrafficArea(reference=REF, side=20000.0, start=0.0, dt=5.0, steps=10)
    t = np.arange(0.0, 31.0)
    f = tf.trajectories(records({"d": (t, 10.0 * t, 0 * t, 100.0 + t)}), area)
    truth = tf.TrafficTruth(f)
    seen = []
    for _ in range(10):
        states, alive = truth.step()
        seen.append((len(alive), bool(alive.all()) if len(alive) else None,
                     float(truth.heights[0]) if len(alive) else None))
    # Born at step 1, gone from step 7 (its last record is at 30 s = step 6), keeping its
    # last height once dead.
    assert seen[0] == (1, True, 105.0) and seen[5] == (1, True, 130.0)
    assert seen[6] == (1, False, 130.0)


def raw(rows: list[tuple[str, float, float, float, float, bool]]) -> pd.DataFrame:
    """Raw records (the file's columns) from ``(icao24, t s, lat, lon, altitude ft,
    onground)`` rows, sorted as :func:`~sensorplan.models.traffic.read_records` sorts them."""
    df = pd.DataFrame(rows, columns=["icao24", "t", "latitude", "longitude", "altitude",
                                     "onground"])
    df["timestamp"] = (df.pop("t") * 1000).astype(np.int64)
    return df.sort_values(["icao24", "timestamp"], kind="stable").reset_index(drop=True)


def test_held_positions_are_left_out_with_the_record_they_repeat():
    # A landing: moving records, then the last position heard held for three records (the
    # first of them included) with onground false, and an altitude from nowhere.
    rows = [("a", t, 48.9 + 1e-3 * t, 2.4, 500.0 - 10 * t, False) for t in range(5)]
    rows += [("a", 5.0 + k, 48.91, 2.4, [100.0, 35000.0, 35000.0][k], False)
             for k in range(3)]
    # Another aircraft at the same position right after: a different aircraft, kept.
    rows += [("b", 0.0, 48.91, 2.4, 3000.0, False), ("b", 1.0, 48.912, 2.4, 3000.0, False)]
    # On the ground, or without a position: left out as before.
    rows += [("c", 0.0, 48.0, 2.0, 0.0, True), ("c", 1.0, np.nan, np.nan, 100.0, False)]
    df = raw(rows)
    keep = tf.airborne(df)
    got = {(c, t) for c, t in zip(df["icao24"], df["timestamp"] // 1000)}
    kept = {(c, t) for c, t, k in zip(df["icao24"], df["timestamp"] // 1000, keep) if k}
    assert kept == {("a", t) for t in range(5)} | {("b", 0), ("b", 1)}
    assert got - kept == {("a", 5), ("a", 6), ("a", 7), ("c", 0), ("c", 1)}


def test_an_altitude_spike_is_left_out_and_a_steep_climb_is_not():
    # 4,625 ft with one record of 36,000 ft: out. A climb of 4,000 ft/min (67 ft/s, below
    # the 100 ft/s taken as real) over 1 s records: every record kept.
    spike = [("s", float(t), 48.8 + 1e-3 * t, 2.2, 36000.0 if t == 3 else 4625.0, False)
             for t in range(7)]
    climb = [("k", float(t), 48.7 + 1e-3 * t, 2.3, 1000.0 + 67.0 * t, False)
             for t in range(7)]
    df = raw(spike + climb)
    keep = tf.airborne(df)
    out = set(zip(df["icao24"][~keep], df["timestamp"][~keep] // 1000))
    assert out == {("s", 3)}
    # The rate scales with the time between records: 3,000 ft in 60 s is a climb, in 1 s a
    # spike (its neighbours agree with each other).
    slow = [("w", 0.0, 48.0, 2.0, 1000.0, False), ("w", 60.0, 48.1, 2.0, 4000.0, False),
            ("w", 120.0, 48.2, 2.0, 1000.0, False)]
    fast = [("f", 0.0, 48.0, 2.0, 1000.0, False), ("f", 1.0, 48.001, 2.0, 4000.0, False),
            ("f", 2.0, 48.002, 2.0, 1000.0, False)]
    df = raw(slow + fast)
    keep = tf.airborne(df)
    assert set(zip(df["icao24"][~keep], df["timestamp"][~keep] // 1000)) == {("f", 1)}


def test_a_missing_records_file_is_one_error_naming_the_command(tmp_path: Path):
    with pytest.raises(ConfigError) as info:
        tf.load_flights(path=tmp_path / "absent.json.gz")
    text = str(info.value)
    assert tf.FETCH_COMMAND in text and "\n" not in text


def test_extract_refuses_a_wheel_that_is_not_the_pinned_one(tmp_path: Path):
    wheel = tmp_path / tf.WHEEL_NAME
    with zipfile.ZipFile(wheel, "w") as zf:
        zf.writestr(tf.MEMBER, b"[]")
    with pytest.raises(ValueError, match="SHA-256"):
        tf.extract(wheel, tmp_path / "out.json.gz")
    assert not (tmp_path / "out.json.gz").exists()


@pytest.mark.skipif(not tf.data_path().is_file(),
                    reason=f"the recorded flights are not fetched ({tf.FETCH_COMMAND})")
def test_the_real_records_give_the_documented_window():
    assert tf.sha256(tf.data_path()) == tf.MEMBER_SHA256
    f = tf.load_flights()
    alive = np.isfinite(f.states[..., 0])
    assert len(f.names) == 64 and int(alive.sum()) == 4925
    assert alive[1:].sum(axis=1).min() == 9 and alive.sum(axis=1).max() == 18
    speed = np.hypot(f.states[..., 2], f.states[..., 3])[alive]
    assert np.median(speed) > 70.0
    # No aircraft hangs in the air: no held position became a target standing still.
    assert np.sum(speed < 1.0) == 0
