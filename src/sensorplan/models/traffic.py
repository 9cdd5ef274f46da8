r"""Recorded air traffic as a scripted truth: ADS-B flights around the Paris airports.

The records are the ``quickstart`` sample of the ``traffic`` package (X. Olive,
github.com/xoolive/traffic), the file ``traffic/data/samples/collections/quickstart.json.gz``
inside its wheel: a JSON array of records with ``timestamp`` (ms since 1970, UTC),
``icao24``, ``callsign``, ``latitude``, ``longitude`` (degrees), ``altitude`` (ft),
``groundspeed`` (kt), ``track`` (degrees), ``vertical_rate`` (ft/min), ``onground`` and
``squawk``, one per aircraft and second from 2021-10-07 12:00 to 15:00 UTC. It is read
from the published wheel, never shipped with this package: :func:`fetch` downloads the
pinned wheel (``pip download``), checks its SHA-256 and extracts that one file into the
cache directory (:func:`data_path`).

Conversion (:func:`trajectories`), every choice in :class:`TrafficArea`:

- **Frame.** Local east/north metres by the equirectangular projection about the reference
  point :math:`(\varphi_0, \lambda_0)`, :math:`e = R \cos\varphi_0 (\lambda - \lambda_0)`,
  :math:`n = R (\varphi - \varphi_0)` (angles in radians, :math:`R` = 6,371,008.8 m, the
  mean Earth radius), then shifted so the reference point is the map's centre. Over the
  80 km map the projection's scale error is below 0.1 % (its error grows with the square of
  the distance from the reference point).
- **Area and window.** The map is the square of side ``side`` about the reference point;
  the run's window starts at ``start`` and lasts ``steps`` steps of ``dt``.
- **Who is a target.** One target per aircraft (``icao24``) and stretch of records without
  a gap longer than ``max_gap`` s; records on the ground, without a position or altitude,
  with a position held from a neighbouring record, or with a one-record altitude spike
  are left out (:func:`airborne`). A target is alive from its first record inside the map
  to its last one (clipped to the window), so targets enter and leave as they did,
  including a landing (its records stop) and a take-off.
- **Resampling.** Positions and altitudes are interpolated linearly in time between
  records at every step of its life; the velocity at a step is the central difference of
  the interpolated positions ``dt / 2`` either side (one-sided at the ends of the records),
  exact on straight constant-speed flight.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._types import FloatArray, IntArray
from ..errors import ConfigError
from .scripted import ScriptedTruth

#: The ``traffic`` release whose wheel holds the records, and its SHA-256 (PyPI's file
#: ``traffic-2.13-py3-none-any.whl``).
TRAFFIC_VERSION = "2.13"
WHEEL_NAME = f"traffic-{TRAFFIC_VERSION}-py3-none-any.whl"
WHEEL_SHA256 = "5e0cd61d931d03103294361542188f08f959a55e862d5cba80ab61291021e66c"
#: The records' path inside the wheel, and the SHA-256 of that file.
MEMBER = "traffic/data/samples/collections/quickstart.json.gz"
MEMBER_SHA256 = "0ef1a97f6b96c31a58e2d9cf58af01a90016eb97472f37718dcba3913c682403"
#: Environment variable naming the records file (else :func:`cache_dir` holds it).
DATA_ENV = "SENSORPLAN_TRAFFIC_DATA"
#: The command that fetches the records (said by every error about them).
FETCH_COMMAND = "python -m sensorplan.models.traffic"
#: Mean Earth radius (m), IUGG.
EARTH_RADIUS = 6371008.8
FEET = 0.3048


@dataclass(frozen=True)
class TrafficArea:
    """Where and when the recorded traffic becomes a scenario's truth.

    Attributes
    ----------
    reference : (lat, lon)   degrees: the map's centre, halfway between the reference
                             points of Paris-Charles de Gaulle (49.0097 N, 2.5479 E) and
                             Paris-Orly (48.7233 N, 2.3794 E), so both airports' approaches
                             are on the map
    side : float             m, the square map's side (80 km: both airports, 16 km either
                             side of the centre, with their final approaches)
    start : float            s since 1970-01-01 UTC: the window's start
    dt : float               s, the scenario's step
    steps : int              steps in the window
    max_gap : float          s; records further apart start a new target
    """

    reference: tuple[float, float] = (48.8665, 2.46365)
    side: float = 80000.0
    start: float = 0.0
    dt: float = 5.0
    steps: int = 360
    max_gap: float = 60.0

    @property
    def world_size(self) -> tuple[float, float]:
        return (self.side, self.side)


@dataclass(frozen=True)
class Flights:
    """Converted flights: what :class:`~sensorplan.models.scripted.ScriptedTruth` replays.

    Attributes
    ----------
    states : (S + 1, M, 4)    ``[x, y, vx, vy]`` on the map (m, m/s); NaN outside a life
    heights : (S + 1, M)      m: the recorded barometric altitude (ft x 0.3048), taken as
                              the height above the radar sites
    birth_step : (M,) int     first step alive, ascending
    death_step : (M,) int     first step absent, -1: alive to the end
    names : tuple of str      ``icao24`` of each target
    """

    states: FloatArray
    heights: FloatArray
    birth_step: IntArray
    death_step: IntArray
    names: tuple[str, ...]


#: The preset's area and window: the 30 minutes from 2021-10-07 13:55:00 UTC, the busiest
#: of the records on this map (the most target-steps of any 30-minute window starting on a
#: whole minute): 64 targets, 9 to 18 alive at once (13.7 on average), 51 of them born
#: after the first step (18 over the edge, 33 inside below 1000 m: take-offs) and 51 gone
#: before the end. Steps of 5 s: an air traffic surveillance radar's revisit (an approach
#: radar turns in 4 to 5 s).
TRAFFIC = TrafficArea(start=1633614900.0)


def project(lat: FloatArray, lon: FloatArray, reference: tuple[float, float]
            ) -> tuple[FloatArray, FloatArray]:
    """East and north (m) of points ``(lat, lon)`` (degrees) from ``reference``: the
    equirectangular projection (module docstring)."""
    lat0, lon0 = (math.radians(v) for v in reference)
    east = EARTH_RADIUS * math.cos(lat0) * (np.radians(lon) - lon0)
    north = EARTH_RADIUS * (np.radians(lat) - lat0)
    return east, north


def _interp(t: Any, tr: Any, values: Any) -> FloatArray:
    """``values`` ``(n, k)`` at times ``tr`` ``(n,)``, linearly interpolated at ``t``."""
    return np.stack([np.interp(t, tr, values[:, c]) for c in range(values.shape[1])], axis=1)


def trajectories(records: Any, area: TrafficArea) -> Flights:
    """Targets of the records in ``area``'s map and window (module docstring).

    Parameters
    ----------
    records : pandas.DataFrame
        Columns ``t`` (s since 1970), ``icao24``, ``latitude``, ``longitude`` (degrees) and
        ``altitude`` (m), airborne records only (:func:`read_records`).
    area : TrafficArea

    Returns
    -------
    Flights, the targets in the order of their birth step (then of their first record).
    """
    S, dt, W = area.steps, area.dt, area.side
    times = area.start + dt * np.arange(S + 1)
    east, north = project(records["latitude"].to_numpy(float),
                          records["longitude"].to_numpy(float), area.reference)
    x, y = east + W / 2, north + W / 2
    inside = (x >= 0) & (x <= W) & (y >= 0) & (y <= W)
    t_all = records["t"].to_numpy(float)
    h_all = records["altitude"].to_numpy(float)
    found: list[tuple[int, int, float, str, FloatArray, FloatArray]] = []
    codes = records["icao24"].to_numpy().astype(str)
    order = np.lexsort((t_all, codes))
    codes, inside = codes[order], inside[order]
    t_all, x, y, h_all = (a[order] for a in (t_all, x, y, h_all))
    # Stretches: one aircraft's records without a gap longer than max_gap.
    cut = np.flatnonzero((codes[1:] != codes[:-1]) | (np.diff(t_all) > area.max_gap)) + 1
    for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(t_all)]):
        tr = t_all[lo:hi]
        if len(tr) < 2 or not inside[lo:hi].any():
            continue
        first, last = tr[inside[lo:hi]][[0, -1]]
        # The steps within [first, last] (a rounding error must not drop an exact step).
        k0 = max(1, math.ceil((first - area.start) / dt - 1e-9))
        k1 = min(S, math.floor((last - area.start) / dt + 1e-9))
        if k1 <= k0:
            continue        # alive for less than two steps of the window
        t = times[k0:k1 + 1]
        pos = np.stack([x[lo:hi], y[lo:hi]], axis=1)
        # Velocity: the interpolated positions' slope over dt, one-sided at the records' ends.
        ta = np.clip(t - dt / 2, tr[0], tr[-1])
        tb = np.clip(t + dt / 2, tr[0], tr[-1])
        v = (_interp(tb, tr, pos) - _interp(ta, tr, pos)) / (tb - ta)[:, None]
        states = np.concatenate([_interp(t, tr, pos), v], axis=1)
        found.append((k0, k1, float(first), str(codes[lo]), states,
                      np.interp(t, tr, h_all[lo:hi])))
    found.sort(key=lambda f: (f[0], f[2], f[3]))
    M = len(found)
    out = np.full((S + 1, M, 4), np.nan)
    heights = np.full((S + 1, M), np.nan)
    for j, (k0, k1, _, _, states, h) in enumerate(found):
        out[k0:k1 + 1, j] = states
        heights[k0:k1 + 1, j] = h
    birth = np.array([f[0] for f in found], dtype=np.int64)
    death = np.array([-1 if f[1] == S else f[1] + 1 for f in found], dtype=np.int64)
    return Flights(out, heights, birth, death, tuple(f[3] for f in found))


class TrafficTruth(ScriptedTruth):
    """Replays :class:`Flights` (as :class:`~sensorplan.models.scripted.ScriptedTruth`),
    with each born target's recorded altitude at the current step in ``heights``
    ``(M_t,)`` (m; a dead target keeps its last one)."""

    def __init__(self, flights: Flights) -> None:
        h = np.array(flights.heights, dtype=float)
        S1 = len(h)
        for j, d in enumerate(flights.death_step):
            if d != -1 and d < S1:
                h[d:, j] = h[d - 1, j]
        self._heights = h
        super().__init__(flights.states, flights.birth_step, flights.death_step)

    def step(self) -> tuple[FloatArray, np.ndarray]:
        states, alive = super().step()
        self.heights = self._heights[self.step_index, :len(alive)].copy()
        return states, alive


_FLIGHTS: dict[tuple[str, TrafficArea], Flights] = {}


def load_flights(area: TrafficArea = TRAFFIC, path: Path | None = None) -> Flights:
    """The records at ``path`` (default :func:`data_path`) converted for ``area``, read once
    per process.

    Raises
    ------
    ConfigError
        The file is not there (:func:`missing_data_error`).
    """
    path = data_path() if path is None else path
    key = (str(path), area)
    if key not in _FLIGHTS:
        if not path.is_file():
            raise missing_data_error(path)
        _FLIGHTS[key] = trajectories(read_records(path), area)
    return _FLIGHTS[key]


# ------------------------------------------------------------------------- the records


def cache_dir() -> Path:
    """Where :func:`fetch` puts the records: ``$XDG_CACHE_HOME/sensorplan/traffic`` (default
    ``~/.cache/sensorplan/traffic``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sensorplan" / "traffic"


def data_path() -> Path:
    """The records file: ``$SENSORPLAN_TRAFFIC_DATA`` if set, else the cache's copy."""
    given = os.environ.get(DATA_ENV)
    return Path(given) if given else cache_dir() / Path(MEMBER).name


def missing_data_error(path: Path) -> ConfigError:
    """The one-line error of a scenario whose records are not there."""
    return ConfigError("scenario.preset", f"traffic: the recorded flights are not at {path}; "
                       f"fetch them with: {FETCH_COMMAND}")


def sha256(path: Path) -> str:
    """Hex SHA-256 of a file."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def extract(wheel: Path, dest: Path) -> Path:
    """Check ``wheel``'s SHA-256 against :data:`WHEEL_SHA256`, extract :data:`MEMBER` to
    ``dest`` (a file) and check its own SHA-256; return ``dest``.

    Raises
    ------
    ValueError
        A checksum that differs (the file is not the pinned release's).
    """
    got = sha256(wheel)
    if got != WHEEL_SHA256:
        raise ValueError(f"{wheel} has SHA-256 {got}, not traffic {TRAFFIC_VERSION}'s "
                         f"{WHEEL_SHA256}")
    dest.parent.mkdir(parents=True, exist_ok=True)
    part = dest.with_name(dest.name + ".part")
    with zipfile.ZipFile(wheel) as zf, zf.open(MEMBER) as src, open(part, "wb") as out:
        shutil.copyfileobj(src, out)
    got = sha256(part)
    if got != MEMBER_SHA256:
        part.unlink()
        raise ValueError(f"{MEMBER} has SHA-256 {got}, not {MEMBER_SHA256}")
    part.replace(dest)
    return dest


def fetch(dest: Path | None = None, wheel: Path | None = None) -> Path:
    """Put the records at ``dest`` (default :func:`data_path`) and return it.

    From ``wheel`` if given (a downloaded ``traffic-2.13-py3-none-any.whl``), else from the
    pinned wheel downloaded by ``pip download traffic==2.13 --no-deps`` into a temporary
    directory (the package itself is not installed). Both checksums are checked
    (:func:`extract`).
    """
    dest = data_path() if dest is None else dest
    if wheel is not None:
        return extract(wheel, dest)
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "pip", "download", f"traffic=={TRAFFIC_VERSION}",
                        "--no-deps", "--only-binary=:all:", "--quiet", "-d", tmp], check=True)
        return extract(Path(tmp) / WHEEL_NAME, dest)


def read_records(path: Path) -> Any:
    """The airborne records of the file at ``path`` as a ``pandas.DataFrame`` with columns
    ``t`` (s since 1970, UTC), ``icao24``, ``latitude``, ``longitude`` (degrees) and
    ``altitude`` (m above mean sea level: the recorded barometric altitude in feet times
    0.3048): the records :func:`airborne` keeps."""
    import pandas as pd

    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", encoding="utf-8") as fh:
        df = pd.DataFrame(json.load(fh))
    df = df.sort_values(["icao24", "timestamp"], kind="stable")
    df = df[airborne(df)]
    return pd.DataFrame({"t": df["timestamp"].to_numpy(float) / 1000.0,
                         "icao24": df["icao24"].astype(str).to_numpy(),
                         "latitude": df["latitude"].to_numpy(float),
                         "longitude": df["longitude"].to_numpy(float),
                         "altitude": df["altitude"].to_numpy(float) * FEET})


#: ft/s: the fastest climb or descent taken as real (6,000 ft/min, beyond an airliner's),
#: and the altitude's own step (the records' altitudes come in 25 ft steps) with margin.
MAX_VERTICAL_RATE = 100.0
ALTITUDE_TOLERANCE = 100.0


def airborne(df: Any, max_vertical_rate: float = MAX_VERTICAL_RATE,
             tolerance: float = ALTITUDE_TOLERANCE) -> np.ndarray:
    """Which raw records (sorted by ``icao24``, then ``timestamp``) are an aircraft in
    flight, with a measured position and altitude.

    Left out:

    - records on the ground (``onground``) or without a position or altitude;
    - records whose position is exactly the aircraft's previous or next record's: a
      position held, not measured anew. After a landing the records go on for minutes with
      the last position heard (at the runway's threshold, or at a gate with altitudes of
      26,000-61,000 ft) and ``onground`` false; kept, they would be aircraft hovering there.
      In flight a position repeats only when no new one was heard, and interpolating
      across it loses nothing;
    - single-record altitude spikes: an altitude that differs from both neighbours' in the
      same direction by more than ``max_vertical_rate`` (ft/s) times the time between
      them plus ``tolerance`` (ft), such as one record of 36,000 ft among 4,625 ft ones.

    Parameters
    ----------
    df : pandas.DataFrame
        The records' columns ``timestamp`` (ms), ``icao24``, ``latitude``, ``longitude``,
        ``altitude`` (ft) and ``onground``.

    Returns
    -------
    (n,) bool, in ``df``'s row order.
    """
    code = df["icao24"].astype(str).to_numpy()
    lat, lon = df["latitude"].to_numpy(float), df["longitude"].to_numpy(float)
    repeat = (code[1:] == code[:-1]) & (lat[1:] == lat[:-1]) & (lon[1:] == lon[:-1])
    # Both ends of a repeat: the first of a held position may be a parked aircraft's too.
    stale = np.r_[False, repeat] | np.r_[repeat, False]
    keep = (~df["onground"].astype(bool).to_numpy() & ~stale
            & df[["latitude", "longitude", "altitude"]].notna().all(axis=1).to_numpy())
    rows = np.flatnonzero(keep)
    t = df["timestamp"].to_numpy(float)[rows] / 1000.0
    h = df["altitude"].to_numpy(float)[rows]
    c = code[rows]
    # Interior records of one aircraft: both neighbours are its own.
    i = np.flatnonzero((c[1:-1] == c[:-2]) & (c[1:-1] == c[2:])) + 1
    up, down = h[i] - h[i - 1], h[i] - h[i + 1]
    spike = ((np.sign(up) == np.sign(down))
             & (np.abs(up) > max_vertical_rate * (t[i] - t[i - 1]) + tolerance)
             & (np.abs(down) > max_vertical_rate * (t[i + 1] - t[i]) + tolerance))
    keep[rows[i[spike]]] = False
    return keep


def main(argv: list[str] | None = None) -> int:
    """``python -m sensorplan.models.traffic [--wheel WHEEL] [--dest FILE]``: fetch the
    records (:func:`fetch`)."""
    import argparse

    parser = argparse.ArgumentParser(
        prog=FETCH_COMMAND, description=f"Fetch the recorded flights of the traffic preset: "
        f"{MEMBER} from the wheel of traffic {TRAFFIC_VERSION} (downloaded with pip, not "
        "installed), checked against pinned SHA-256 sums.")
    parser.add_argument("--wheel", type=Path, help="a downloaded wheel to read instead")
    parser.add_argument("--dest", type=Path, help=f"where to write it (default {data_path()})")
    args = parser.parse_args(argv)
    try:
        path = fetch(args.dest, args.wheel)
    except (ValueError, OSError, subprocess.CalledProcessError, KeyError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
