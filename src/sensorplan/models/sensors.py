r"""Sensor parameters, validated at the boundary, and the per-sensor table the radar reads.

:class:`SensorParams` is what users write (one frozen value per sensor, with the defaults of
the paper's radar). :func:`radar_table` turns a sequence of them into one float64 row per
sensor, computed once, with the columns of :data:`COLUMNS`; the compiled radar model
(:mod:`sensorplan.models.radar`) and every kernel take such rows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from .._types import FloatArray
from ..errors import ConfigError

#: Detection models of a sensor.
DETECTION_MODELS = ("ideal", "swerling1")


def _param(default: Any, limit: str | None = None, *, positive: bool = False,
           angle: bool = False, choices: tuple[str, ...] = (), noun: str = "") -> Any:
    """A :class:`SensorParams` field with its rule, the one declaration that the checks of
    :meth:`SensorParams.validate` and the file model
    (:data:`sensorplan.config.validation.SensorParamsModel`) read.

    ``limit`` names its range in :data:`sensorplan.limits.RANGES` (each move distance for
    ``moves``); ``positive`` also refuses 0; ``angle`` marks radians (files may give
    ``<name>_deg``); ``choices`` are the allowed strings, called ``noun`` in errors.
    """
    meta = {"limit": limit, "positive": positive, "angle": angle, "choices": choices,
            "noun": noun}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class SensorParams:
    """Platform and radar parameters of one sensor (defaults: docs/model.md, section 2).

    Attributes
    ----------
    altitude : float
        Platform altitude z_i (m).
    moves : tuple of float
        Move distances s (m); each gives the 8 lattice directions.
    max_turn : float
        Largest heading change per epoch (rad).
    fov_half_angle : float
        Azimuth half-width of the field of view (rad).
    min_ground_range, max_ground_range : float
        Ground-range band of the field of view (m).
    depression : float
        Boresight depression below the horizon (rad).
    snr_ref_db, range_ref : float
        SNR (dB) at the reference slant range (m).
    beamwidth : float
        Beamwidth (rad).
    monopulse_slope : float
        Monopulse slope (dimensionless).
    range_resolution : float
        Range resolution (m).
    range_error_floor, azimuth_error_floor : float
        Standard deviations (m, rad) of the measurement errors that do not fall with the
        SNR (quantisation, the antenna's and the processing's own errors), added in
        quadrature to the SNR model's: a radar is never more precise than these, however
        close the target. 0 (the default, the paper's radar) leaves the SNR model alone.
    detection : {"ideal", "swerling1"}
        ``ideal``: every look at a target in the field of view detects it; ``swerling1``:
        it is detected with probability ``Pd = Pfa ** (1 / (1 + SNR))`` (a Swerling 1
        target and a square-law detector), SNR at the target's range.
    false_alarm_probability : float
        Pfa per resolution cell, in (0, 1); sets the detection threshold (``swerling1``).
    clutter_rate : float
        Expected number of false detections per look (Poisson), uniform over the look's
        sensing region (>= 0).
    """

    altitude: float = _param(500.0, "altitude", positive=True)
    moves: tuple[float, ...] = _param((20.0, 40.0), "length")
    max_turn: float = _param(math.pi / 4, "max_turn", angle=True)
    fov_half_angle: float = _param(math.pi / 6, "fov_half_angle", positive=True, angle=True)
    min_ground_range: float = _param(250.0, "ground_range", positive=True)
    max_ground_range: float = _param(450.0, "ground_range", positive=True)
    depression: float = _param(math.radians(40.0), "depression", angle=True)
    snr_ref_db: float = _param(15.0, "snr_ref_db")
    range_ref: float = _param(600.0, "range_ref", positive=True)
    beamwidth: float = _param(math.radians(3.0), "beamwidth", positive=True, angle=True)
    monopulse_slope: float = _param(1.6, "monopulse_slope", positive=True)
    range_resolution: float = _param(30.0, "range_resolution", positive=True)
    range_error_floor: float = _param(0.0, "range_error_floor")
    azimuth_error_floor: float = _param(0.0, "azimuth_error_floor", angle=True)
    detection: str = _param("ideal", choices=DETECTION_MODELS, noun="detection model")
    false_alarm_probability: float = _param(1e-6, "probability")
    clutter_rate: float = _param(0.0, "clutter_rate")

    def validate(self, prefix: str = "sensor") -> None:
        """Raise :class:`ConfigError` naming the field ``prefix.<name>`` if a value breaks
        its declared rule (:func:`_param`): a choice, a finite number (each move distance
        for ``moves``), > 0 where ``positive``, its range in
        :data:`sensorplan.limits.RANGES` (angles in radians: ``fov_half_angle`` in (0, pi],
        ``max_turn`` in [0, pi], ``depression`` in (0, pi/2], ``beamwidth`` in
        [1e-4, pi/2]); and ``min_ground_range <= max_ground_range``. (Input files also bound
        the radar's precision: :func:`sensorplan.limits.check_sensor_precision`.)
        """
        from ..limits import MAX_MOVE_DISTANCES, RANGES, check_count, coerce

        numbers: dict[str, tuple[float, ...]] = {}
        for f in fields(self):
            value, rule = getattr(self, f.name), f.metadata
            if rule["choices"]:
                if value not in rule["choices"]:
                    raise ConfigError(f"{prefix}.{f.name}", f"unknown {rule['noun']} "
                                      f"{value!r}; choose from {', '.join(rule['choices'])}")
                continue
            try:
                numbers[f.name] = coerce(tuple[float, ...], value) if f.name == "moves" \
                    else (coerce(float, value),)
            except ValueError as exc:
                raise ConfigError(f"{prefix}.{f.name}", str(exc)) from None
        for f in fields(self):
            if f.metadata["positive"] and numbers[f.name][0] <= 0:
                raise ConfigError(f"{prefix}.{f.name}", "must be > 0")
        if len(self.moves) == 0:
            raise ConfigError(f"{prefix}.moves", "must list at least one move distance")
        if any(m <= 0 for m in numbers["moves"]):
            raise ConfigError(f"{prefix}.moves", "move distances must be > 0")
        check_count(len(self.moves), MAX_MOVE_DISTANCES, f"{prefix}.moves", "move distances")
        for f in fields(self):
            if f.metadata["limit"] is None:
                continue
            hint = (f" (angles are in radians; degrees are written {f.name}_deg)"
                    if f.metadata["angle"] else "")
            for v in numbers[f.name]:
                RANGES[f.metadata["limit"]].check(v, f"{prefix}.{f.name}", hint)
        if numbers["min_ground_range"][0] > numbers["max_ground_range"][0]:
            raise ConfigError(f"{prefix}.min_ground_range", "must be <= max_ground_range")


#: Sensor fields that are angles (radians); files may give each in degrees as
#: ``<name>_deg`` instead.
ANGLE_FIELDS = tuple(f.name for f in fields(SensorParams) if f.metadata["angle"])


#: Columns of a radar table row (:func:`radar_table`), in order. ``snr0`` is the linear SNR
#: at ``range_ref``; ``var_r`` and ``var_phi`` are the noise constants with
#: :math:`\sigma_r^2 = c_r r^4 + f_r^2` and
#: :math:`\sigma_\phi^2 = c_\phi r^4 / \cos^2\psi + f_\phi^2`, ``floor_r2`` and
#: ``floor_phi2`` the squared error floors :math:`f_r^2, f_\phi^2`;
#: ``swerling`` is 1 for Swerling 1 detection, 0 for ideal; ``log_pfa`` is ln Pfa;
#: ``clutter_rate`` the false detections per look and ``area`` the sensing region's ground
#: area (m^2). The last column belongs to planning: ``aware`` is 1 when planned looks count
#: their detection probability and the clutter.
COLUMNS = ("altitude", "altitude2", "cos_depression", "sin_depression", "fov_half_angle",
           "min_ground_range", "max_ground_range", "snr0", "range_ref", "var_r", "var_phi",
           "floor_r2", "floor_phi2", "swerling", "log_pfa", "clutter_rate", "area", "aware")
(ALTITUDE, ALTITUDE2, COS_DEP, SIN_DEP, FOV, G_MIN, G_MAX, SNR0, RANGE_REF, VAR_R, VAR_PHI,
 FLOOR_R2, FLOOR_PHI2, SWERLING, LOG_PFA, CLUTTER_RATE, AREA, AWARE) = range(len(COLUMNS))


def radar_table(sensors: Sequence[SensorParams] | SensorParams, *,
                aware: bool = False) -> FloatArray:
    r"""One row of radar constants per sensor, shaped ``(N, len(COLUMNS))``.

    With :math:`s_0 = 10^{\mathrm{snr_{ref}}/10}` the SNR model
    :math:`\mathrm{SNR} = s_0 (r_{ref}/r)^4` gives
    :math:`\sigma_r^2 = \Delta r^2 / (2\,\mathrm{SNR}) = c_r r^4` and
    :math:`\sigma_\phi^2 = (\beta/\cos\psi)^2 / (k_m^2\, 2\,\mathrm{SNR})
    = c_\phi r^4/\cos^2\psi` with

    .. math:: c_r = \frac{\Delta r^2}{2 s_0 r_{ref}^4},\qquad
              c_\phi = \frac{\beta^2}{k_m^2\, 2 s_0 r_{ref}^4};

    the error floors add :math:`f_r^2` and :math:`f_\phi^2` to these variances.

    Parameters
    ----------
    sensors : SensorParams or sequence of SensorParams (scalar fields)
    aware : bool
        Planned looks count their detection probability and the clutter (see
        :func:`sensorplan.models.radar.look`).

    Returns
    -------
    (N, len(COLUMNS)) float64, C-contiguous; a single SensorParams gives N = 1.
    """
    seq = (sensors,) if isinstance(sensors, SensorParams) else tuple(sensors)
    out = np.empty((len(seq), len(COLUMNS)))
    for n, p in enumerate(seq):
        snr0 = 10.0 ** (float(p.snr_ref_db) / 10.0)
        two_s0_r4 = 2.0 * snr0 * float(p.range_ref) ** 4
        alt = float(p.altitude)
        dep = float(p.depression)
        fov, gmin, gmax = (float(p.fov_half_angle), float(p.min_ground_range),
                           float(p.max_ground_range))
        out[n] = (alt, alt * alt, math.cos(dep), math.sin(dep), fov, gmin, gmax, snr0,
                  float(p.range_ref), float(p.range_resolution) ** 2 / two_s0_r4,
                  (float(p.beamwidth) / float(p.monopulse_slope)) ** 2 / two_s0_r4,
                  float(p.range_error_floor) ** 2, float(p.azimuth_error_floor) ** 2,
                  float(p.detection == "swerling1"), math.log(float(p.false_alarm_probability)),
                  float(p.clutter_rate), fov * (gmax * gmax - gmin * gmin), float(aware))
    return out
