"""Figures and animations of runs (matplotlib is imported here and in the report only)."""
