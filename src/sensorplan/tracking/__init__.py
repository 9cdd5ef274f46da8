"""Tracking: filters (EKF, IMM), association, missed looks and the known map, behind a protocol."""
