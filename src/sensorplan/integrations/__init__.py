"""Bridges to other libraries. Each submodule imports its library; this package imports none.

- :mod:`sensorplan.integrations.stonesoup`: Stone Soup (the optional extra
  ``sensorplan[stonesoup]``): state converters, a measurement model of the radar, actionable
  platform and sensor types, a sensor manager running any registered planner, and a
  mutual-information reward for Stone Soup's own sensor managers.
"""
