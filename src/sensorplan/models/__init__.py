"""The physical models, once each: angles, target motion and truth, the sensors and the radar."""
