r"""The radar model: what a sensor measures and what it can see, in one place.

Every consumer calls these compiled functions, directly (the planner's kernels) or through
the batched wrappers of :mod:`sensorplan.models.radar.batch`: the tracker's update
(:mod:`sensorplan.tracking.ekf`), the simulator's measurements of the truth
(:mod:`sensorplan.simulation.run`), the planner's look information
(:mod:`sensorplan.planners._chains_nb`, :mod:`sensorplan.planners.information`), the missed-look
update (:mod:`sensorplan.tracking.missed`) and the
Stone Soup bridge. A change to the radar is one edit here. The slow numpy version of the same
model lives in the tests (``tests/radar_reference.py``), as the independent second
computation.

A sensor is one row of a radar table (:func:`sensorplan.models.sensors.radar_table`). For a target
at ground offset :math:`(dx, dy)` from a platform at altitude :math:`z` with heading
:math:`\theta`:

.. math::
    g = \sqrt{dx^2 + dy^2},\quad r = \sqrt{g^2 + z^2},\quad \phi = \mathrm{atan2}(dy, dx),

    H' = \begin{bmatrix} dx/r & dy/r \\ -dy/g^2 & dx/g^2 \end{bmatrix}
    \quad (\text{Jacobian of } [r, \phi] \text{ w.r.t. the ground position;
    velocity columns are zero}),

    \cos\psi = \frac{\cos\delta\,(dx\cos\theta + dy\sin\theta) + \sin\delta\, z}{r}
    \quad (\text{angle between line of sight and boresight, depression } \delta),

    \sigma_r^2 = c_r r^4 + f_r^2,\qquad
    \sigma_\phi^2 = c_\phi\, r^4 / \cos^2\psi + f_\phi^2
    \quad (\text{the SNR model and the error floors, constants in the table row}).

The field of view (the sensing region) is :math:`g \in [g_{min}, g_{max}]`,
:math:`|\mathrm{wrap}(\phi - \theta)| \le f` and :math:`\cos\psi > 0`, bounds inclusive with
a tolerance of :data:`RANGE_TOL` m and :data:`ANGLE_TOL` rad (a point placed exactly on an
edge can compute a rounding error outside it).

In planning, the target's ground position is uncertain, :math:`N(\bar x, C)`; the
probability that it is in view is, linearised at the mean with ground range and azimuth
treated as independent,

.. math::
    p_{vis} = [\Phi(\tfrac{g_{max}-\bar g}{s_g}) - \Phi(\tfrac{g_{min}-\bar g}{s_g})]
              [\Phi(\tfrac{f-d}{s_\phi}) - \Phi(\tfrac{-f-d}{s_\phi})],\quad
    s_g^2 = u^T C u,\ s_\phi^2 = v^T C v / \bar g^2,

with :math:`u` the unit ground vector toward the mean, :math:`v` perpendicular to it and
:math:`d = \mathrm{wrap}(\bar\phi - \theta)`; :math:`p_{vis} = 0` at the nadir or when
:math:`\cos\psi \le 0` at the mean. A planned look counts with the information
:math:`p\, H'^T R^{-1} H'` (its noise is :math:`R / p`); looks with :math:`p` below
:data:`P_VIS_MIN` do not count.
"""


from __future__ import annotations

import math

import numpy as np

from ..._compiled.jit import njit  # numba.njit, once numba's kernel cache is known to be writable
from ..sensors import (ALTITUDE, ALTITUDE2, AREA, AWARE, CLUTTER_RATE, COS_DEP, FOV,
                       FLOOR_PHI2, FLOOR_R2, G_MAX, G_MIN, LOG_PFA, RANGE_REF, SIN_DEP, SNR0,
                       SWERLING, VAR_PHI, VAR_R)

#: A sensor's radar row: an array (a row of the radar table) or a tuple of its values
#: (:func:`row_values`); every function here takes either.
Row = np.ndarray | tuple
#: Tolerance (m) of the inclusive ground-range bounds of the field of view.
RANGE_TOL = 1e-9
#: Tolerance (rad) of the inclusive azimuth bounds of the field of view.
ANGLE_TOL = 1e-12
#: Planned looks less likely than this to see their target do not count.
P_VIS_MIN = 1e-6
#: Constants of the clutter factor of detection-aware planning,
#: q2 = 1 / (1 + b Pd^-c lam^d) (see :func:`clutter_factor`; scripts/irf_fit.py).
IRF_B, IRF_C, IRF_D = 22.64, 1.134, 1.005
#: A planned look whose predicted ground range is more than this many standard deviations
#: outside the range band does not count: its in-band mass is below Ncdf(-6) ~ 1e-9.
BAND_SIGMAS = 6.0
#: Beyond this many standard deviations both normal tails are so small that
#: ``Ncdf(b) - Ncdf(a)`` with ``a <= -SURE_SIGMAS <= SURE_SIGMAS <= b`` is exactly 1.0 in
#: floating point (``Ncdf(b)`` rounds to 1, ``Ncdf(a) < 2**-54`` leaves 1 unchanged): the
#: two ``erfc`` calls are skipped there, with the same result bit for bit.
SURE_SIGMAS = 8.5


# ------------------------------------------------------------------ scalar kernels


@njit(cache=True, error_model="numpy")
def row_values(row: np.ndarray) -> tuple:
    """A radar row's values as a tuple, for a kernel's inner loop.

    Every function of this module takes the row as an array or as this tuple (they only
    index it by the column constants). A tuple is passed by value, while an array argument
    costs two atomic reference count updates per call, about a tenth of a planned look's
    time. Its length must follow :data:`sensorplan.models.sensors.COLUMNS` (a test checks).
    """
    return (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[9],
            row[10], row[11], row[12], row[13], row[14], row[15], row[16], row[17])


@njit(cache=True, error_model="numpy")
def wrap(a: float) -> float:
    """Wrap an angle to (-pi, pi] (as :func:`sensorplan.models.angles.wrap_angle`)."""
    two_pi = 2.0 * math.pi
    x = math.pi - a
    # x % two_pi is x itself for 0 <= x < two_pi (the usual case): skip the floating modulo.
    w = math.pi - (x if 0.0 <= x < two_pi else x % two_pi)
    return w + two_pi if w <= -math.pi else w


@njit(cache=True, error_model="numpy")
def cos_psi(row: Row, dx: float, dy: float, cos_h: float, sin_h: float,
            r: float) -> float:
    """Cosine of the angle between the line of sight and the boresight."""
    return (row[COS_DEP] * (dx * cos_h + dy * sin_h) + row[SIN_DEP] * row[ALTITUDE]) / r


@njit(cache=True, error_model="numpy")
def noise_variances(row: Row, r2: float, cpsi: float) -> tuple[float, float]:
    """Range (m^2) and azimuth (rad^2) noise variances at slant range^2 ``r2``: the SNR
    model's plus the squared error floors (a zero floor adds exactly nothing)."""
    r4 = r2 * r2
    return row[VAR_R] * r4 + row[FLOOR_R2], row[VAR_PHI] * r4 / (cpsi * cpsi) + row[FLOOR_PHI2]


@njit(cache=True, error_model="numpy")
def in_band(row: Row, g: float) -> bool:
    """Whether ground range ``g`` lies in the field of view's range band."""
    return row[G_MIN] - RANGE_TOL <= g <= row[G_MAX] + RANGE_TOL


@njit(cache=True, error_model="numpy")
def in_wedge(row: Row, d: float) -> bool:
    """Whether the azimuth offset ``d`` from the heading lies in the field of view's wedge."""
    return abs(d) <= row[FOV] + ANGLE_TOL


@njit(cache=True, error_model="numpy")
def visible(row: Row, dx: float, dy: float, heading: float) -> bool:
    """Whether a target at ground offset ``(dx, dy)`` is in the field of view."""
    g = math.sqrt(dx * dx + dy * dy)
    if not in_band(row, g):
        return False
    if not in_wedge(row, wrap(math.atan2(dy, dx) - heading)):
        return False
    r = math.sqrt(g * g + row[ALTITUDE2])
    return cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r) > 0.0


@njit(cache=True, error_model="numpy")
def hidden(buildings: np.ndarray, sx: float, sy: float, z: float, qx: float,
           qy: float) -> bool:
    """Whether a building blocks the line of sight from a sensor to a ground point.

    The sight line runs from the sensor at ``(sx, sy, z)`` to the target at ``(qx, qy, 0)``;
    a building ``(x0, y0, x1, y1, h)`` is the box ``[x0, x1] x [y0, y1] x [0, h]``. The
    target is hidden when the line passes through the inside of a box; a line that only
    touches a wall, an edge or the roof (grazing) is not blocked.
    """
    dx, dy = qx - sx, qy - sy
    for b in range(buildings.shape[0]):
        x0, y0, x1, y1, h = (buildings[b, 0], buildings[b, 1], buildings[b, 2],
                             buildings[b, 3], buildings[b, 4])
        # Along the line P(s) = sensor + s (target - sensor), s in [0, 1], the height
        # z (1 - s) is below the roof for s > 1 - h / z.
        lo, hi = max(0.0, 1.0 - h / z), 1.0
        if dx == 0.0:
            if not x0 < sx < x1:
                continue
        else:
            t1, t2 = (x0 - sx) / dx, (x1 - sx) / dx
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
        if dy == 0.0:
            if not y0 < sy < y1:
                continue
        else:
            t1, t2 = (y0 - sy) / dy, (y1 - sy) / dy
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
        if lo < hi:
            return True
    return False


#: Nodes and weights of the 3-point Gauss-Hermite rule for a standard normal (exact for
#: polynomials up to degree 5); their tensor product gives the occlusion factor's 9 points.
_GH_NODES = (-math.sqrt(3.0), 0.0, math.sqrt(3.0))
_GH_WEIGHTS = (1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0)


@njit(cache=True, error_model="numpy")
def in_sight_probability(buildings: np.ndarray, sx: float, sy: float, z: float, mx: float,
                         my: float, c00: float, c01: float, c11: float,
                         probabilistic: bool) -> float:
    r"""Probability that no building hides a target at ``N((mx, my), C)`` from a sensor.

    ``probabilistic``: the weighted share of 9 fixed points of the position distribution
    that are in sight, the tensor product of the 3-point Gauss-Hermite rule mapped through
    the Cholesky factor of ``C`` (nodes :math:`0, \pm\sqrt 3` standard deviations, weights
    2/3 and 1/6 per axis): deterministic, in [0, 1], and exactly 1 without buildings.
    Otherwise: 1 if the mean is in sight, else 0.
    """
    if buildings.shape[0] == 0:
        return 1.0
    if not probabilistic:
        return 0.0 if hidden(buildings, sx, sy, z, mx, my) else 1.0
    l00 = math.sqrt(max(c00, 0.0))
    l10 = c01 / l00 if l00 > 0.0 else 0.0
    l11 = math.sqrt(max(c11 - l10 * l10, 0.0))
    total = 0.0
    n_hidden = 0
    for a in range(3):
        for b in range(3):
            qx = mx + l00 * _GH_NODES[a]
            qy = my + l10 * _GH_NODES[a] + l11 * _GH_NODES[b]
            if hidden(buildings, sx, sy, z, qx, qy):
                n_hidden += 1
            else:
                total += _GH_WEIGHTS[a] * _GH_WEIGHTS[b]
    # The weights sum to 1 only up to rounding: all in sight is exactly 1, none exactly 0.
    if n_hidden == 0:
        return 1.0
    return total if n_hidden < 9 else 0.0


@njit(cache=True, error_model="numpy")
def detection_probability(row: Row, r2: float) -> float:
    r"""Probability of detecting a target in view at slant range^2 ``r2``.

    ``ideal`` detection: 1. Swerling 1 with a square-law detector:
    :math:`P_d = P_{fa}^{1/(1 + \mathrm{SNR})}`, :math:`\mathrm{SNR} = s_0 (r_{ref}/r)^4`.
    """
    if row[SWERLING] == 0.0:
        return 1.0
    ratio = row[RANGE_REF] * row[RANGE_REF] / r2
    snr = row[SNR0] * ratio * ratio
    return math.exp(row[LOG_PFA] / (1.0 + snr))


@njit(cache=True, error_model="numpy")
def clutter_density(row: Row, r: float) -> float:
    r"""Density of false alarms in the measurement space ``(r, phi)`` at slant range ``r``.

    ``clutter_rate`` :math:`\lambda` false alarms per look fall uniformly in ground area over
    the sensing region of area :math:`A` (the ``area`` column). With :math:`r^2 = g^2 + z^2`
    the ground area element is :math:`g\,dg\,d\phi = r\,dr\,d\phi`, so

    .. math:: \rho(r) = \lambda\, r / A \quad [1 / (\mathrm{m\ rad})],

    which integrates to :math:`\lambda` over the region. 0 without clutter.
    """
    return row[CLUTTER_RATE] * r / row[AREA]


@njit(cache=True, error_model="numpy")
def clutter_factor(row: Row, pd: float, r: float, s00: float, s01: float,
                   s11: float) -> float:
    r"""Information reduction of a look by clutter, for detection-aware planning.

    A probabilistic data association filter in clutter gets, from one look, a fraction of
    the information of a look whose detection is certainly the target's: the information
    reduction factor (Kershaw and Evans 1994; Niu, Willett and Bar-Shalom 2001). Relative to
    clutter-free detection it is approximated by

    .. math:: q_2 = 1 / (1 + b\, P_d^{-c} \lambda_w^{d})

    with :math:`\lambda_w = \rho \sqrt{\det S}` the clutter density in whitened
    measurement coordinates: :math:`\rho = \lambda r / A` (``clutter_rate`` false
    detections uniform over the sensing region of ground area ``A``, in range and azimuth
    at slant range ``r``) and ``S`` (entries s00, s01, s11) the innovation covariance. The
    functional form is Kershaw and Evans's; the constants were fitted (in log space) to a
    Monte Carlo evaluation of the factor's definition for a 0.999 gate over
    :math:`P_d \in [0.3, 1]`, :math:`\lambda_w \in [0.003, 3]`, which they match within
    15 % (relative; scripts/irf_fit.py). Without clutter it is exactly 1.
    """
    lam = row[CLUTTER_RATE]
    if lam == 0.0:
        return 1.0
    det = s00 * s11 - s01 * s01
    lam_w = clutter_density(row, r) * math.sqrt(max(det, 0.0))
    if lam_w <= 0.0:
        return 1.0
    return 1.0 / (1.0 + IRF_B * pd ** -IRF_C * lam_w ** IRF_D)


@njit(cache=True, error_model="numpy")
def measure(row: Row, dx: float, dy: float, heading: float
            ) -> tuple[float, float, float, float, float, float, float, float, bool]:
    """Noise-free measurement, Jacobian, noise and visibility of one look.

    Returns
    -------
    r, phi : slant range (m) and azimuth (rad)
    h00, h01, h10, h11 : the ground-position Jacobian ``H'`` (row-major)
    var_r, var_phi : noise variances (m^2, rad^2); ``inf`` azimuth variance if cos psi = 0
    visible : bool

    Degenerate geometry never raises: the Jacobian at the nadir (g = 0) is non-finite, as
    numpy's division would give.
    """
    g2 = dx * dx + dy * dy
    r2 = g2 + row[ALTITUDE2]
    r = math.sqrt(r2)
    phi = math.atan2(dy, dx)
    cpsi = cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r)
    var_r, var_phi = noise_variances(row, r2, cpsi)
    seen = in_band(row, math.sqrt(g2)) and in_wedge(row, wrap(phi - heading)) and cpsi > 0.0
    return r, phi, dx / r, dy / r, -dy / g2, dx / g2, var_r, var_phi, seen


@njit(cache=True, error_model="numpy")
def inverse(row: Row, r: float, phi: float, heading: float
            ) -> tuple[float, float, float, float, float]:
    r"""Ground offset of a measurement ``[r, phi]`` and its linearised covariance.

    The inverse of the measurement model: :math:`g = \sqrt{r^2 - z^2}` (0 if the slant range
    is below the altitude), :math:`(dx, dy) = g (\cos\phi, \sin\phi)`, and with the noise
    ``R`` of the model evaluated at that point and :math:`J = \partial(dx, dy) /
    \partial(r, \phi) = [[r/g \cos\phi, -g \sin\phi], [r/g \sin\phi, g \cos\phi]]`, the
    covariance :math:`J R J^T`.

    Returns
    -------
    dx, dy : ground offset from the sensor (m)
    c00, c01, c11 : its covariance (m^2)
    """
    g = math.sqrt(max(r * r - row[ALTITUDE2], 0.0))
    c, s = math.cos(phi), math.sin(phi)
    dx, dy = g * c, g * s
    cpsi = cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r)
    var_r, var_phi = noise_variances(row, r * r, cpsi)
    rg = r / max(g, 1e-9)
    j00, j01, j10, j11 = rg * c, -g * s, rg * s, g * c
    return (dx, dy, j00 * j00 * var_r + j01 * j01 * var_phi,
            j00 * j10 * var_r + j01 * j11 * var_phi, j10 * j10 * var_r + j11 * j11 * var_phi)


@njit(cache=True, error_model="numpy")
def _ncdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


@njit(cache=True, error_model="numpy")
def _interval(lo: float, hi: float, sd: float) -> float:
    """``Ncdf(hi/sd) - Ncdf(lo/sd)``; a zero ``sd`` gives the indicator of ``lo <= 0 <= hi``."""
    if sd > 0.0:
        a, b = lo / sd, hi / sd
        if a <= -SURE_SIGMAS and b >= SURE_SIGMAS:
            return 1.0                      # what the difference rounds to (see SURE_SIGMAS)
        return _ncdf(b) - _ncdf(a)
    return 1.0 if (lo <= 0.0 and hi >= 0.0) else 0.0


@njit(cache=True, error_model="numpy")
def range_weight(row: Row, ux: float, uy: float, g: float, c00: float, c01: float,
                 c11: float, probabilistic: bool) -> float:
    """The range-band factor of a look's weight, for ground range ``g`` along ``(ux, uy)``.

    ``probabilistic``: the probability that the ground range ``N(g, u^T C u)`` lies in the
    band; otherwise the 0/1 band test of the mean.
    """
    if not probabilistic:
        return 1.0 if in_band(row, g) else 0.0
    sd = math.sqrt(max(ux * ux * c00 + 2.0 * ux * uy * c01 + uy * uy * c11, 0.0))
    gmin, gmax = row[G_MIN], row[G_MAX]
    # More than 6 sd outside the band the mass is below Ncdf(-6) ~ 1e-9, far below
    # P_VIS_MIN: skip the two erfc calls (most looks of a large candidate set are far out).
    if sd > 0.0 and (g > gmax + BAND_SIGMAS * sd or g < gmin - BAND_SIGMAS * sd):
        return 0.0
    return _interval(gmin - g, gmax - g, sd)


@njit(cache=True, error_model="numpy")
def reach(row: Row, c00: float, c01: float, c11: float, probabilistic: bool) -> float:
    """A ground range (m) beyond which no planned look at the target can count.

    :func:`range_weight` is 0 for every ground range above it, in any direction, when the
    target's position covariance has the entries ``c00, c01, c11``: ``g_max + 6 sd`` with
    ``sd`` the largest standard deviation of that covariance (``probabilistic``), else the
    band's edge; both with a margin for round-off. Planners use it to skip far candidates
    without evaluating them.
    """
    if probabilistic:
        lam = 0.5 * (c00 + c11) + math.sqrt(0.25 * (c00 - c11) ** 2 + c01 * c01)
        edge = row[G_MAX] + BAND_SIGMAS * math.sqrt(max(lam, 0.0) * (1.0 + 1e-9))
    else:
        edge = row[G_MAX] + RANGE_TOL
    return edge * (1.0 + 1e-12) + 1e-9


@njit(cache=True, error_model="numpy")
def look(row: Row, buildings: np.ndarray, px: float, py: float, dx: float, dy: float,
         heading: float, c00: float, c01: float, c11: float,
         probabilistic: bool) -> tuple[float, float, float, float]:
    """Weight ``p`` and information ``p H'^T R^{-1} H'`` (w00, w01, w11) of a planned look.

    The sensor is at ground point ``(px, py)``, the target's predicted mean at offset
    ``(dx, dy)`` from it. ``probabilistic``: ``p = p_vis`` of a target at ``N((dx, dy), C)``,
    C given by its entries c00, c01, c11, times the probability that no building hides it
    (:func:`in_sight_probability`); otherwise ``p`` is the 0/1 visibility of the mean. With
    the row's ``aware`` flag, ``p`` is further multiplied by the detection probability at
    the mean and the clutter factor (:func:`detection_probability`, :func:`clutter_factor`).
    A look with ``p < P_VIS_MIN`` gives zeros.
    """
    p, g2, g = look_range(row, buildings, px, py, dx, dy, c00, c01, c11, probabilistic)
    if p < P_VIS_MIN:
        return 0.0, 0.0, 0.0, 0.0
    return look_in_range(row, dx, dy, g2, g, p, heading, c00, c01, c11, probabilistic)


@njit(cache=True, error_model="numpy")
def look_range(row: Row, buildings: np.ndarray, px: float, py: float, dx: float,
               dy: float, c00: float, c01: float, c11: float,
               probabilistic: bool) -> tuple[float, float, float]:
    """The heading-free first part of :func:`look`: the range factor of the weight
    (:func:`range_weight`; 0 at the nadir) times the in-sight probability, with ``g^2`` and
    ``g``. Buildings are tested only for a look that passes the range test."""
    p, g2, g = look_range_clear(row, dx, dy, c00, c01, c11, probabilistic)
    if p >= P_VIS_MIN and buildings.shape[0] > 0:
        p *= in_sight_probability(buildings, px, py, row[ALTITUDE], px + dx, py + dy, c00,
                                  c01, c11, probabilistic)
    return p, g2, g


@njit(cache=True, error_model="numpy")
def look_range_clear(row: Row, dx: float, dy: float, c00: float, c01: float,
                     c11: float, probabilistic: bool) -> tuple[float, float, float]:
    """:func:`look_range` where no building stands: its range factor, ``g^2`` and ``g``."""
    g2 = dx * dx + dy * dy
    if g2 == 0.0:
        return 0.0, g2, 0.0
    g = math.sqrt(g2)
    return range_weight(row, dx / g, dy / g, g, c00, c01, c11, probabilistic), g2, g


@njit(cache=True, error_model="numpy")
def look_in_range(row: Row, dx: float, dy: float, g2: float, g: float, p: float,
                  heading: float, c00: float, c01: float, c11: float,
                  probabilistic: bool) -> tuple[float, float, float, float]:
    """The rest of :func:`look` given :func:`look_range`'s ``p >= P_VIS_MIN``, ``g2``, ``g``
    (a planner computes that part once for looks that differ only in heading)."""
    return look_at_azimuth(row, dx, dy, g2, g, p, math.atan2(dy, dx), heading, c00, c01, c11,
                           probabilistic)


@njit(cache=True, error_model="numpy")
def look_at_azimuth(row: Row, dx: float, dy: float, g2: float, g: float, p: float,
                    azimuth: float, heading: float, c00: float, c01: float, c11: float,
                    probabilistic: bool) -> tuple[float, float, float, float]:
    """:func:`look_in_range` given the azimuth ``atan2(dy, dx)`` (a planner that has just
    computed the same bearing for the heading rule passes it on)."""
    ux, uy = dx / g, dy / g
    r2 = g2 + row[ALTITUDE2]
    r = math.sqrt(r2)
    cpsi = cos_psi(row, dx, dy, math.cos(heading), math.sin(heading), r)
    if cpsi <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    d = wrap(azimuth - heading)
    if probabilistic:
        sd_phi = math.sqrt(max(uy * uy * c00 - 2.0 * ux * uy * c01 + ux * ux * c11, 0.0)) / g
        fov = row[FOV]
        p *= _interval(-fov - d, fov - d, sd_phi)
        if p < P_VIS_MIN:
            return 0.0, 0.0, 0.0, 0.0
    elif not in_wedge(row, d):
        return 0.0, 0.0, 0.0, 0.0
    var_r, var_phi = noise_variances(row, r2, cpsi)
    if row[AWARE] != 0.0:
        # Detection-aware planning: the look also counts its chance of detecting the target
        # and the information that clutter takes away (innovation covariance S = H C H^T + R
        # at the predicted mean).
        pd = detection_probability(row, r2)
        a0, a1, b0, b1 = dx / r, dy / r, -dy / g2, dx / g2
        ca0, ca1 = c00 * a0 + c01 * a1, c01 * a0 + c11 * a1
        s00 = a0 * ca0 + a1 * ca1 + var_r
        s01 = b0 * ca0 + b1 * ca1
        cb0, cb1 = c00 * b0 + c01 * b1, c01 * b0 + c11 * b1
        s11 = b0 * cb0 + b1 * cb1 + var_phi
        p *= pd * clutter_factor(row, pd, r, s00, s01, s11)
        if p < P_VIS_MIN:
            return 0.0, 0.0, 0.0, 0.0
    # H'^T R^-1 H' in closed form: a a^T / var_r + b b^T / var_phi with the rows of H',
    # a = (dx, dy) / r and b = (-dy, dx) / g^2.
    wr = p / (var_r * r2)
    wp = p / (var_phi * g2 * g2)
    return p, wr * dx * dx + wp * dy * dy, (wr - wp) * dx * dy, wr * dy * dy + wp * dx * dx
