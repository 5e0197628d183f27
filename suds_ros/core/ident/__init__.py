"""Identification: SUDS regression, intervals, batch and streaming estimators, scoring."""
