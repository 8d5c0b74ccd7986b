"""Adaptive conformal ellipses: coverage theory on exchangeable and shifted streams, causality,
an independent per-prediction reference, streams kept apart, and bad input named."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.traj.conformal import AdaptiveConformal, ConformalError, ellipse_hits

LEVELS = (0.5, 0.9, 0.95)


def stream(n, h=3, scale=None, seed=0, step=1):
    """n predictions, one every ``step`` time units, each revealed 4 units later; d^2 of a 2-D
    Gaussian error (chi-square(2) = exponential of mean 2) times ``scale`` (n,)."""
    rng = np.random.default_rng(seed)
    s = rng.exponential(2.0, (n, h)) * (1.0 if scale is None else np.asarray(scale)[:, None])
    tp = np.arange(n) * step
    return s, tp, tp + 4


def reference_radii(scores, tp, tr, prior, levels, gamma, window):
    """Straight from Gibbs & Candès 2021 and split conformal, one prediction at a time: before
    predicting at t, the outcomes with t_revealed <= t not yet seen move each step's a once by
    gamma (alpha - their share outside), NaN steps skipped; the radius is the
    ceil((1 - a)(M + 1))-th smallest of the M finite scores among the last ``window`` revealed
    (``window`` evenly spaced prior rows first), +inf beyond M, 0 for 1 - a <= 0 (a rank within
    1e-9 of a whole number is that number)."""
    n, h = scores.shape
    alpha = 1 - np.asarray(levels)
    out = np.zeros((len(levels), n, h))
    a = np.tile(alpha[:, None], (1, h))
    if len(prior) > window:
        prior = prior[[k * len(prior) // window for k in range(window)]]
    seen, pool, last_t = set(), [row for row in prior], None
    for i in np.argsort(tp, kind="stable"):
        if tp[i] != last_t:                     # a new prediction time: reveal, then one step
            new = [j for j in np.argsort(tr, kind="stable") if tr[j] <= tp[i] and j not in seen]
            for k in range(h):
                errs = [scores[j, k] > out[:, j, k] for j in new if not np.isnan(scores[j, k])]
                if errs:
                    a[:, k] += gamma * (alpha - np.mean(errs, axis=0))
            seen.update(new)
            pool += [scores[j] for j in new]
            last_t = tp[i]
        recent = np.array(pool[-window:])
        for li in range(len(levels)):
            for k in range(h):
                finite = np.sort(recent[:, k][~np.isnan(recent[:, k])])
                q, m = 1 - a[li, k], len(finite)
                rank = int(np.ceil(q * (m + 1) - 1e-9))   # a whole number, whatever rounding
                out[li, i, k] = 0.0 if q <= 0 else (np.inf if rank > m else finite[rank - 1])
    return out


@pytest.mark.parametrize("gamma", [0.0, 0.005])
def test_exchangeable_stream_covers_each_level(gamma):
    """Scores exchangeable with the prior: every level's coverage within 1 pp of nominal (the
    conformal guarantee; 6,000 predictions x 3 steps)."""
    s, tp, tr = stream(6000)
    prior, _, _ = stream(300, seed=1)
    radii = AdaptiveConformal(LEVELS, gamma, 300).radii(s, tp, tr, np.zeros(6000, int), prior)
    np.testing.assert_allclose(ellipse_hits(s, radii), LEVELS, atol=0.01)


def test_a_shift_is_followed_where_fixed_radii_fail():
    """The error scale quadruples halfway (a new scene): the prior's fixed radii cover far less
    than nominal over the stream, the adaptive ellipses within 2 pp at every level (Gibbs &
    Candès 2021, Prop. 4.1)."""
    n = 6000
    s, tp, tr = stream(n, scale=np.r_[np.ones(n // 2), np.full(n // 2, 4.0)], seed=2)
    prior, _, _ = stream(300, seed=3)
    fixed = AdaptiveConformal(LEVELS, 0.0, 10**9)
    r_fixed = fixed.radii(s, tp, np.full(n, 10**9), np.zeros(n, int), prior)  # nothing revealed
    assert ellipse_hits(s, r_fixed)[1] < 0.75
    radii = AdaptiveConformal(LEVELS, 0.005, 300).radii(s, tp, tr, np.zeros(n, int), prior)
    np.testing.assert_allclose(ellipse_hits(s, radii), LEVELS, atol=0.02)


def test_a_crowded_stream_keeps_its_ellipses_bounded():
    """30 predictions per time (a crowded frame), revealed 12 times later, the error scale
    doubling halfway: one ACI step per time keeps the 90 and 95 % ellipses bounded (a step per
    outcome would swing the level past 1) and still covers within 2 pp; the size report
    says so."""
    rng = np.random.default_rng(14)
    n_t, per = 400, 30
    tp = np.repeat(np.arange(n_t), per)
    scale = np.where(tp >= n_t // 2, 2.0, 1.0)[:, None]
    s = rng.exponential(2.0, (n_t * per, 3)) * scale
    prior = rng.exponential(2.0, (500, 3))
    conf = AdaptiveConformal(LEVELS, 0.005, 300)
    rep = conf.coverage(s, tp, tp + 12, np.zeros(len(s), int), prior)
    for p in (50, 90, 95):
        assert rep[f"online_coverage_{p}"] == pytest.approx(p / 100, abs=0.02), p
        assert rep[f"online_unbounded_{p}"] < 0.01, p
    # Gaussian radii before the shift (exp. mean 2: the 90 % radius is sqrt(2 ln 10) = 2.15)
    assert 2.0 < rep["online_radius_90"] < 2 * 2.15


def test_a_prediction_never_sees_a_later_outcome():
    """Changing every score revealed after time T leaves the radii of predictions made by T
    unchanged bit for bit; the radii made later do change."""
    s, tp, tr = stream(400, seed=4, step=2)
    prior, _, _ = stream(50, seed=5)
    conf = AdaptiveConformal(LEVELS, 0.01, 80)
    before = conf.radii(s, tp, tr, np.zeros(400, int), prior)
    t_cut = 300
    later = tr > t_cut
    s2 = s.copy()
    s2[later] = np.random.default_rng(6).exponential(20.0, s2[later].shape)
    after = conf.radii(s2, tp, tr, np.zeros(400, int), prior)
    made = tp <= t_cut
    np.testing.assert_array_equal(after[:, made], before[:, made])
    assert not np.array_equal(after[:, ~made], before[:, ~made])


def test_equal_to_the_one_prediction_at_a_time_reference():
    """Several predictions per time (ETH/UCY: every pedestrian of a frame), NaN steps, levels
    pushed to both ends by a large gamma: the batched recursion equals the reference."""
    rng = np.random.default_rng(7)
    n, h = 160, 4
    tp = np.sort(rng.integers(0, 60, n))
    tr = tp + rng.integers(1, 12, n)
    s = rng.exponential(2.0, (n, h)) * np.where(np.arange(n) > 80, 6.0, 1.0)[:, None]
    s[rng.random((n, h)) < 0.05] = np.nan
    prior = rng.exponential(2.0, (15, h))
    for gamma, window in [(0.0, 15), (0.05, 25), (0.4, 10)]:
        got = AdaptiveConformal(LEVELS, gamma, window).radii(s, tp, tr, np.zeros(n, int), prior)
        want = reference_radii(s, tp, tr, prior, LEVELS, gamma, window)
        np.testing.assert_allclose(got, want, rtol=1e-12)
        if gamma == 0.4:  # the large step really pushed levels past both ends
            assert np.isinf(got).any() and (got == 0).any()


def test_nan_steps_neither_count_nor_move_a_level():
    s, tp, tr = stream(500, seed=8)
    prior, _, _ = stream(100, seed=9)
    conf = AdaptiveConformal(LEVELS, 0.01, 100)
    base = conf.radii(s, tp, tr, np.zeros(500, int), prior)
    s_nan = np.concatenate([s, np.full((500, 1), np.nan)], axis=1)
    prior_nan = np.concatenate([prior, np.full((100, 1), np.nan)], axis=1)
    got = conf.radii(s_nan, tp, tr, np.zeros(500, int), prior_nan)
    np.testing.assert_array_equal(got[..., :3], base)
    assert np.all(np.isinf(got[..., 3]))  # no score at that step: no finite ellipse
    assert ellipse_hits(s_nan, got).tolist() == ellipse_hits(s, base).tolist()


def test_streams_are_kept_apart():
    """Each recording starts from the prior: a stream's radii do not depend on another's."""
    a, tpa, tra = stream(300, seed=10)
    b, tpb, trb = stream(200, scale=np.full(200, 9.0), seed=11)
    prior, _, _ = stream(60, seed=12)
    conf = AdaptiveConformal(LEVELS, 0.01, 60)
    both = conf.radii(np.r_[a, b], np.r_[tpa, tpb], np.r_[tra, trb],
                      np.r_[np.zeros(300, int), np.ones(200, int)], prior)
    np.testing.assert_array_equal(both[:, :300], conf.radii(a, tpa, tra, np.zeros(300, int),
                                                            prior))
    np.testing.assert_array_equal(both[:, 300:], conf.radii(b, tpb, trb, np.zeros(200, int),
                                                            prior))


def test_bad_input_is_named():
    s, tp, tr = stream(10)
    conf = AdaptiveConformal(LEVELS)
    with pytest.raises(ConformalError, match="row 0 has t_predicted 0, t_revealed 0"):
        conf.radii(s, tp, tp, np.zeros(10, int), s)
    with pytest.raises(ConformalError, match="prior"):
        conf.radii(s, tp, tr, np.zeros(10, int), s[:, :2])
    with pytest.raises(ConformalError, match="t_predicted"):
        conf.radii(s, tp[:5], tr, np.zeros(10, int), s)
    with pytest.raises(ConformalError, match="stream"):
        conf.radii(s, tp, tr, np.full(10, 0.5), s)
    for bad in [dict(levels=(0.5, 1.0)), dict(levels=(0.9, 0.901)), dict(gamma=-0.1),
                dict(window=0), dict(window=2.5), dict(window=True)]:
        with pytest.raises(ConformalError):
            AdaptiveConformal(**{"levels": LEVELS, **bad})
