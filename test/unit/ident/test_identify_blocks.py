"""Long recordings are identified a block at a time: the same model and scores as all at once."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, _Samples, split_cycles
from suds_ros.core.ident.scoring import ScoreSums, score_prediction
from suds_ros.core.ident.sysid import SudsRegressor


def _fits(rec, **blocks):
    train, test = split_cycles(rec, 12, 8)
    whole = SudsIdentifier().fit(train)
    blocked = SudsIdentifier(IdentifyConfig(**blocks)).fit(train)
    return train, test, whole, blocked


def test_blockwise_identify_equals_whole(purcell3_run) -> None:
    """Blocks of 700 intervals (the phase still whole): model, CV table and scores to 1e-9."""
    train, test, whole, blocked = _fits(purcell3_run, block_samples=700)
    assert blocked._blockwise(train, training=True) and blocked._blockwise(test, training=False)
    assert blocked.cv_scores_.keys() == whole.cv_scores_.keys()
    for k, v in whole.cv_scores_.items():
        assert blocked.cv_scores_[k] == pytest.approx(v, rel=1e-9, abs=1e-12)
    assert blocked.regressor_.config == whole.regressor_.config
    np.testing.assert_allclose(blocked.regressor_.coef_, whole.regressor_.coef_, rtol=1e-9,
                               atol=1e-9 * np.abs(whole.regressor_.coef_).max())
    np.testing.assert_allclose(blocked.output_template_coef_, whole.output_template_coef_, rtol=1e-9, atol=1e-12)
    a, b = whole.scores(test), blocked.scores(test)
    for g in ("gamma_body", "gamma_passive"):
        assert getattr(b, g) == pytest.approx(getattr(a, g), abs=1e-9)
    assert b.n_samples == a.n_samples
    for c in a.rms_model:
        assert b.rms_model[c] == pytest.approx(a.rms_model[c], rel=1e-9)
        assert b.rms_template[c] == pytest.approx(a.rms_template[c], rel=1e-9)


def test_selection_on_every_kth_row_and_fit_on_all(purcell3_run) -> None:
    """Above ``select_max_rows`` the selection sees every k-th interval; the regression all of them."""
    train, _ = split_cycles(purcell3_run, 12, 8)
    m = train.n_samples - 1
    blocked = SudsIdentifier(IdentifyConfig(block_samples=700, select_max_rows=m // 3 + 1)).fit(train)
    got = dict(blocked.cv_scores_)
    s = blocked._samples(train, blocked._phase(train, fit=False))
    X = blocked.features(train, s.iv, s.ph)
    k = 3  # the smallest stride leaving at most m // 3 + 1 rows
    chosen = blocked._select_model(train, X[::k], _Samples(None, s.ph[::k], s.Y[::k], None),  # type: ignore[arg-type]
                                   blocked.output_template(s.ph[::k]))
    assert got.keys() == blocked.cv_scores_.keys()
    for key, v in blocked.cv_scores_.items():
        assert got[key] == pytest.approx(v, rel=1e-9, abs=1e-12)
    assert blocked.regressor_.config == chosen
    want = SudsRegressor(chosen, n_actuated=len(train.actuated), kernel_scale=blocked.kernel_scale_).fit(X, s.Y)
    np.testing.assert_allclose(blocked.regressor_.coef_, want.coef_, rtol=1e-9, atol=1e-9 * np.abs(want.coef_).max())


def test_blockwise_scores_without_poses_at_the_ends(purcell3_run) -> None:
    """Held-out data whose pose stream stops early: the joints score every interval, the body
    those with poses (as the pose intervals of the whole path score it)."""
    train, test = split_cycles(purcell3_run, 12, 8)
    test = replace(test, pose_t=test.pose_t[5:-3], pose=test.pose[5:-3])
    whole = SudsIdentifier().fit(train)
    blocked = SudsIdentifier(IdentifyConfig(block_samples=700)).fit(train)
    assert blocked._blockwise(test, training=False)
    a, b = score_prediction(whole.predict(test)), blocked.scores(test)
    assert b.gamma_body == pytest.approx(a.gamma_body, abs=1e-9)
    assert b.gamma_passive == pytest.approx(a.gamma_passive, abs=1e-9)


def test_phase_in_blocks_is_close_to_the_whole_transform(purcell3_run) -> None:
    """The phaser fitted on a leading part and applied in blocks with context: close to whole."""
    ident = SudsIdentifier().fit(purcell3_run)
    whole = ident._phase(purcell3_run, fit=False)
    ident.config = IdentifyConfig(phase_block_samples=400, phase_margin_samples=300)
    blocks = ident._phase(purcell3_run, fit=False)
    spc = purcell3_run.n_samples / 20  # samples per cycle
    inner = slice(int(2 * spc), int(-2 * spc))  # away from the recording's own edges
    assert np.abs(blocks - whole)[inner].max() < 0.05  # 3 cycles of context here; 30 by default
    assert np.abs(np.diff(blocks)).max() < 4 * np.abs(np.diff(whole)).max()  # joined without jumps


def test_score_sums_equal_score_prediction(purcell3_run) -> None:
    train, test = split_cycles(purcell3_run, 12, 8)
    ident = SudsIdentifier().fit(train)
    p = ident.predict(test)
    sums = ScoreSums(p.channels)
    for a in range(0, p.t.size, 333):
        sums.add(p.truth[a:a + 333], p.model[a:a + 333], p.template[a:a + 333])
    got, want = sums.scores(), score_prediction(p)
    assert got.gamma_body == pytest.approx(want.gamma_body, abs=1e-12)
    assert got.gamma_passive == pytest.approx(want.gamma_passive, abs=1e-12)
    assert got.n_samples == want.n_samples


def test_block_settings_are_checked() -> None:
    with pytest.raises(SudsConfigError, match="`block_samples`: expected ≥ 1, got 0"):
        IdentifyConfig(block_samples=0)
    with pytest.raises(SudsConfigError, match="`select_max_rows`: expected ≥ 1, got 0"):
        IdentifyConfig(select_max_rows=0)
    with pytest.raises(SudsConfigError, match="`phase_margin_samples`: expected ≥ 0, got -1"):
        IdentifyConfig(phase_margin_samples=-1)


def test_short_recordings_are_prepared_once_when_scored(purcell3_run, monkeypatch: pytest.MonkeyPatch) -> None:
    """At or below ``block_samples`` scores() goes straight to predict(): the recording is brought onto
    its grid once, as before the block-wise path."""
    train, test = split_cycles(purcell3_run, 12, 8)
    ident = SudsIdentifier().fit(train)
    calls: list[int] = []
    real = SudsIdentifier._prepared
    monkeypatch.setattr(SudsIdentifier, "_prepared", lambda self, rec: calls.append(1) or real(self, rec))
    ident.scores(test)
    assert len(calls) == 1
    ident.config = IdentifyConfig(block_samples=700)
    ident.scores(test)
    assert len(calls) == 2  # long: checked for the block-wise path, then scored a block at a time


def test_a_long_recording_with_bridged_samples_is_identified_a_block_at_a_time(purcell3_run) -> None:
    """Bridged shape samples (runs of lost messages, one across a block boundary): each block leaves
    out the intervals over them, and the model, CV table and scores are the whole path's."""
    train, test = split_cycles(purcell3_run, 12, 8)
    mask = np.zeros(train.n_samples, dtype=bool)
    mask[400:430] = True
    mask[695:705] = True  # across the first block's end
    mask[1100] = True
    lossy = replace(train, bridged=mask)
    held = np.zeros(test.n_samples, dtype=bool)
    held[300:320] = True
    held[699:702] = True
    lossy_test = replace(test, bridged=held)
    whole = SudsIdentifier().fit(lossy)
    blocked = SudsIdentifier(IdentifyConfig(block_samples=700)).fit(lossy)
    assert blocked._blockwise(lossy, training=True) and blocked._blockwise(lossy_test, training=False)
    assert blocked.cv_scores_.keys() == whole.cv_scores_.keys()
    for k, v in whole.cv_scores_.items():  # summation order: 5e-10 relative without a bridged sample, 1.3e-9 with
        assert blocked.cv_scores_[k] == pytest.approx(v, rel=1e-8, abs=1e-12)
    np.testing.assert_allclose(blocked.regressor_.coef_, whole.regressor_.coef_, rtol=1e-9,
                               atol=1e-9 * np.abs(whole.regressor_.coef_).max())
    np.testing.assert_allclose(blocked.output_template_coef_, whole.output_template_coef_, rtol=1e-9, atol=1e-12)
    a, b = whole.scores(lossy_test), blocked.scores(lossy_test)
    assert b.n_samples == a.n_samples < whole.scores(test).n_samples
    for g in ("gamma_body", "gamma_passive"):
        assert getattr(b, g) == pytest.approx(getattr(a, g), abs=1e-9)
    plain = SudsIdentifier().fit(train)
    assert not np.allclose(plain.regressor_.coef_, whole.regressor_.coef_)  # the bridged intervals were left out
