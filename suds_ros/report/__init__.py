"""Reports: live-prediction scores, identification figures, diagnosis figures and summaries."""
