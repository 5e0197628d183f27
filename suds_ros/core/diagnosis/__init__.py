"""Sim-vs-real diagnosis: locate mismatches, name the missing physics, fit it, show the gain."""

from suds_ros.core.diagnosis.pipeline import *  # noqa: F401,F403  (split into stage modules below)
