"""Choosing among fixed model candidates online, by their prequential error.

The batch identifier picks its model by cross-validation; a live estimator cannot (it keeps
sufficient statistics, not rows).  Instead it fits several candidate configurations side by
side — each an exact incremental least-squares fit of its own — and scores every chunk with
each candidate *before* the candidate learns from it (prequential evaluation, Dawid 1984).  The
candidate with the lowest recent prequential loss is the one published.  Which candidate is
current is learned from the data; no candidate's hyperparameters ever change.

Loss of a chunk: per output group (body velocity, passive rates), Σ|prediction error| over
Σ|phase-only template error| (the Γ ratio), averaged over the groups.  Losses are discounted
by ``memory`` chunks (weight ½ after that many), so a larger model takes over once the data
support it — small models win the first cycles, the richer ones later.
"""

from __future__ import annotations

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.estimator import is_fitted
from suds_ros.core.ident.sysid import AveragedTargets, SudsRegressor


class PrequentialSelector:
    """Candidate regressors fitted on one stream; the current one has the lowest discounted loss.

    Parameters
    ----------
    candidates : list of SudsRegressor
        Unfitted regressors (same joints, any configurations); the first is current at the start.
    memory : float
        Chunks after which a chunk's loss counts half.

    Attributes
    ----------
    loss_ : (k,) discounted prequential loss of each candidate (summed ratios).
    weight_ : float, the discounted number of chunks scored.
    current_ : int, index of the candidate with the lowest loss.

    The attributes exist from the first chunk on; the candidates themselves are fitted in place
    (each keeps its own sufficient statistics).
    """

    def __init__(self, candidates: list[SudsRegressor], memory: float = 20.0) -> None:
        self.candidates = candidates
        self.memory = memory

    @property
    def current(self) -> SudsRegressor:
        """The candidate published now (the first one before any chunk)."""
        return self.candidates[vars(self).get("current_", 0)]

    def score_then_fit(self, X: FloatArray, Y: FloatArray, avg: AveragedTargets,
                       ref_body: FloatArray, ref_rest: FloatArray) -> None:
        """Score the chunk with every fitted candidate, then add it to all of them.

        ``ref_body`` (q, nb) and ``ref_rest`` (m, c) are the template's absolute errors on the
        chunk's averaged (body) and row outputs, the loss's denominators.
        """
        nb = len(avg.columns)
        if "loss_" not in vars(self):  # the first chunk
            self.loss_ = np.zeros(len(self.candidates))
            self.weight_ = 0.0
            self.current_ = 0
        # a group without channels (the passive rates of a fully actuated robot) has no error to
        # score: the loss averages the groups that have one (before 2026-12-06 such a robot was
        # never scored, so its first candidate stayed current whatever the data said)
        body = nb > 0 and ref_body.sum() > 0
        rest = Y.shape[1] > 0 and ref_rest.sum() > 0
        if all(is_fitted(c) for c in self.candidates) and (body or rest):
            decay = 0.5 ** (1.0 / self.memory)
            for i, c in enumerate(self.candidates):
                ratios = []
                if body:
                    pred_body = np.asarray(avg.weights @ c.predict(avg.X)[:, :nb])  # type: ignore[operator]
                    ratios.append(np.abs(pred_body - avg.y).sum() / ref_body.sum())
                if rest:
                    ratios.append(np.abs(c.predict(X)[:, nb:] - Y).sum() / ref_rest.sum())
                self.loss_[i] = decay * self.loss_[i] + float(np.mean(ratios))
            self.weight_ = decay * self.weight_ + 1.0
            self.current_ = int(np.argmin(self.loss_))
        for c in self.candidates:
            c.partial_fit(X, Y, avg)
