"""The radar: the one model of what a sensor measures and what it can see.

:mod:`sensorplan.models.radar.model` holds the model itself, as compiled scalar functions over one
sensor's row of a radar table (:func:`sensorplan.models.sensors.radar_table`): range, azimuth,
Jacobian, noise, field of view, line of sight, detection probability, clutter, and a
planned look's information. A change to the radar is one edit there.
:mod:`sensorplan.models.radar.batch` loops those functions over batches and wraps them for numpy;
the tracker, the simulator, the planner, the missed-look update and the Stone Soup bridge
all call them. The slow numpy version of the same model lives in the tests
(``tests/radar_reference.py``) as the independent second computation.
"""

from .batch import (clutter_densities, clutter_points, detectable_points,
                    detectable_quadrature, detection_probabilities, false_alarms, hidden_looks,
                    inverse_looks, look_information, measure_looks, visible_points, warm_up)
from .model import (ANGLE_TOL, BAND_SIGMAS, IRF_B, IRF_C, IRF_D, P_VIS_MIN, RANGE_TOL,
                    clutter_density, clutter_factor, cos_psi, detection_probability, hidden,
                    in_band, in_sight_probability, in_wedge, inverse, look, look_at_azimuth,
                    look_in_range, look_range, look_range_clear, measure, noise_variances,
                    range_weight, reach, row_values, visible, wrap)

__all__ = ["ANGLE_TOL", "BAND_SIGMAS", "IRF_B", "IRF_C", "IRF_D", "P_VIS_MIN", "RANGE_TOL",
           "clutter_densities", "clutter_density", "clutter_factor", "clutter_points",
           "cos_psi", "false_alarms", "detectable_points",
           "detectable_quadrature", "detection_probabilities", "detection_probability",
           "hidden", "hidden_looks",
           "in_band", "in_sight_probability", "in_wedge", "inverse", "inverse_looks", "look",
           "look_at_azimuth", "look_in_range", "look_information", "look_range",
           "look_range_clear", "measure", "measure_looks", "noise_variances", "range_weight",
           "reach", "row_values", "visible",
           "visible_points", "warm_up", "wrap"]
