"""Gait optimisation: model-based on the physics (:mod:`.physics`)."""
