"""Sim-vs-real diagnosis: locate mismatches, name the missing physics, fit it, show the gain.

The stages live in their own modules (:mod:`.data`, :mod:`.replay`, :mod:`.floor`,
:mod:`.locate`, :mod:`.naming`, :mod:`.refine`); :mod:`.pipeline` runs them and
:mod:`.report` holds the configuration and the frozen report.
"""

from suds_ros.core.diagnosis.locate import excess_improvement
from suds_ros.core.diagnosis.naming import catalogue_candidates
from suds_ros.core.diagnosis.pipeline import diagnose, diagnose_recording, discover_formulas, rank_effects
from suds_ros.core.diagnosis.report import (
    CandidateScore,
    Channels,
    DiagnoseConfig,
    DiagnosisReport,
    FittedEffect,
    Located,
)

__all__ = [
    "CandidateScore",
    "Channels",
    "DiagnoseConfig",
    "DiagnosisReport",
    "FittedEffect",
    "Located",
    "catalogue_candidates",
    "diagnose",
    "diagnose_recording",
    "discover_formulas",
    "excess_improvement",
    "rank_effects",
]
