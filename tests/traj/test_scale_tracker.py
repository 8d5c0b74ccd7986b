"""Scale-tracking ellipses: the radius a chi-square(2) stream's quantile implies, long-run coverage
under a shift and in a short bursty scene, an independent one-outcome-at-a-time reference,
causality, the choice among both kinds of online ellipses, and bad input named."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.traj.conformal import (AdaptiveConformal, ConformalError, ellipse_hits,
                                      select_on_held_out_streams)
from blindspot.traj.scale_tracker import ScaleTracker

LEVELS = (0.5, 0.9, 0.95)


def stream(n, h=3, scale=None, seed=0, step=1, delay=4):
    """n predictions, one every ``step`` time units, step k revealed ``delay`` + k units later;
    d^2 of a 2-D Gaussian error (chi-square(2): exponential of mean 2) times ``scale`` (n,)."""
    rng = np.random.default_rng(seed)
    s = rng.exponential(2.0, (n, h)) * (1.0 if scale is None else np.asarray(scale)[:, None])
    tp = np.arange(n, dtype=float) * step
    return s, tp, tp[:, None] + delay + np.arange(h)


def reference_radii(scores, tp, tr, prior, levels, eta, kappa, n0):
    """The bookkeeping written out one prediction and one outcome at a time (it checks the
    order of reveals, NaN steps, streams and crowded times, not the theory): before predicting
    at t, every finite outcome revealed by t and not yet used, in reveal order, moves its
    level's tracker by eta (1[log(score / q) > tracker] - alpha) and adds 1[score > the radius
    its prediction was given] - alpha to the level's miss sum S; the radius is q exp(tracker +
    kappa S / (used + n0)), q the prior's 'higher' quantile of the level at the step, raised to
    the lower level's where it falls below (``levels`` ascending)."""
    n, h = scores.shape
    out = np.zeros((len(levels), n, h))
    q = np.array([[np.quantile(prior[~np.isnan(prior[:, k]), k], lv, method="higher")
                   for k in range(h)] for lv in levels])
    theta = np.zeros(len(levels))
    miss = np.zeros(len(levels))
    used = []
    pending = sorted(((tr[j, k], j, k) for j in range(n) for k in range(h)
                      if not np.isnan(scores[j, k])), key=lambda x: x[0])
    for i in np.argsort(tp, kind="stable"):
        while pending and pending[0][0] <= tp[i]:
            _, j, k = pending.pop(0)
            used.append((j, k))
            for li, lv in enumerate(levels):
                theta[li] += eta * (float(np.log(scores[j, k] / q[li, k]) > theta[li]) - (1 - lv))
                miss[li] += float(scores[j, k] > out[li, j, k]) - (1 - lv)
        for li in range(len(levels)):
            out[li, i] = q[li] * np.exp(theta[li] + kappa * miss[li] / (len(used) + n0))
        out[:, i] = np.maximum.accumulate(out[:, i], axis=0)     # levels ascending: nested
    return out


def bursty_drifting_scene(seed):
    """180 predictions in bursts of 3 per time, 12 steps each revealed at its own time, the
    error scale drifting from 3x to 9x a chi-square(2)'s; and that scale per prediction."""
    rng = np.random.default_rng(seed)
    tp = np.repeat(np.r_[np.arange(30), 100 + np.arange(30)], 3).astype(float)
    scale = np.geomspace(3, 9, tp.size)
    s = rng.exponential(2.0, (tp.size, 12)) * scale[:, None]
    return s, tp, tp[:, None] + 1 + np.arange(12), scale


def true_radius(levels, scale):
    """(L, N) the level's quantile of scale x chi-square(2): -2 ln(1 - level) x scale."""
    return -2 * np.log(1 - np.asarray(levels))[:, None] * np.asarray(scale)[None]


@pytest.mark.parametrize("kappa", [0.0, 10.0])
def test_the_radius_settles_on_the_chi_square_quantile_of_the_stream(kappa):
    """Prior at scale 1, the stream at scale 6: over the last 500 of 4,000 predictions the
    radius of each level is within 10 % of 6 x chi-square(2)'s quantile, -2 ln(1 - level) (an
    exponential of mean 2), with the tracker alone and with the coverage correction, and the
    coverage over the stream within 1 pp of nominal."""
    s, tp, tr = stream(4000, scale=np.full(4000, 6.0), seed=1)
    prior, _, _ = stream(500, seed=2)
    radii = ScaleTracker(LEVELS, 0.05, kappa).radii(s, tp, tr, np.zeros(4000, int), prior)
    truth = true_radius(LEVELS, [6.0])[:, 0]
    np.testing.assert_allclose(radii[:, -500:].mean(axis=(1, 2)), truth, rtol=0.10)
    np.testing.assert_allclose(ellipse_hits(s, radii), LEVELS, atol=0.01)


def test_a_short_bursty_scene_whose_scale_drifts_is_covered_with_radii_of_its_scale():
    """Short new scenes (:func:`bursty_drifting_scene`; ETH/UCY eth's test scene has 181
    predictions) with errors 3-9x the prior's: over 8 draws the tracker with its correction
    covers each level within 2 pp on average, and its radii stay near the scene's quantile
    (median |ln(radius / quantile)| below 0.35 at every level: the radius within a factor 1.4;
    a tracker stepping on every outcome of a burst judged against its stale radius swung by
    orders of magnitude). The sliding window, its prior rescaled to the scene's median, lags
    the drift and covers its 50 % ellipses less than 42 % of the time."""
    tracked, window, off = [], [], []
    for seed in range(8):
        s, tp, tr, scale = bursty_drifting_scene(seed)
        prior = np.random.default_rng(100 + seed).exponential(2.0, (2000, 12))
        one = np.zeros(tp.size, int)
        r = ScaleTracker(LEVELS).radii(s, tp, tr, one, prior)
        tracked.append(ellipse_hits(s, r))
        off.append(np.abs(np.log(r / true_radius(LEVELS, scale)[:, :, None])))
        window.append(ellipse_hits(s, AdaptiveConformal(LEVELS, 0.005, 150, 3).radii(
            s, tp, tr, one, prior)))
    np.testing.assert_allclose(np.mean(tracked, axis=0), LEVELS, atol=0.02)
    assert np.all(np.median(np.concatenate(off, axis=1), axis=(1, 2)) < 0.35)
    assert np.mean(window, axis=0)[0] < 0.42


def test_a_crowded_stream_keeps_radii_of_its_scale():
    """30 predictions per time (a crowded frame, as ETH/UCY univ's up to 57), revealed 12
    times later, the error scale doubling halfway: coverage within 2 pp at every level and the
    radii within a factor 1.3 of the scene's quantile at the median."""
    rng = np.random.default_rng(14)
    n_t, per = 400, 30
    tp = np.repeat(np.arange(n_t), per).astype(float)
    scale = np.where(tp >= n_t // 2, 2.0, 1.0)
    s = rng.exponential(2.0, (n_t * per, 3)) * scale[:, None]
    prior = rng.exponential(2.0, (500, 3))
    r = ScaleTracker(LEVELS).radii(s, tp, tp + 12, np.zeros(len(s), int), prior)
    np.testing.assert_allclose(ellipse_hits(s, r), LEVELS, atol=0.02)
    ratio = np.abs(np.log(r / true_radius(LEVELS, scale)[:, :, None]))
    assert np.all(np.median(ratio, axis=(1, 2)) < np.log(1.3))


def test_a_shift_is_followed():
    """The error scale quadruples halfway: every level within 1.5 pp of nominal."""
    n = 6000
    s, tp, tr = stream(n, scale=np.r_[np.ones(n // 2), np.full(n // 2, 4.0)], seed=4)
    prior, _, _ = stream(300, seed=5)
    radii = ScaleTracker(LEVELS, 0.05, 10.0).radii(s, tp, tr, np.zeros(n, int), prior)
    np.testing.assert_allclose(ellipse_hits(s, radii), LEVELS, atol=0.015)


@pytest.mark.parametrize("kappa", [0.0, 7.0])
def test_equal_to_the_one_outcome_at_a_time_reference(kappa):
    """Crowded times (5 predictions each), NaN steps, two streams: equal to the reference."""
    rng = np.random.default_rng(6)
    tp = np.repeat(np.arange(60), 5).astype(float)
    s = rng.exponential(2.0, (tp.size, 4)) * rng.uniform(0.3, 3.0, (tp.size, 1))
    s[rng.random(s.shape) < 0.1] = np.nan
    tr = tp[:, None] + 1 + np.arange(4) * 2
    prior = rng.exponential(2.0, (100, 4))
    group = (np.arange(tp.size) >= 150).astype(int)
    conf = ScaleTracker(LEVELS, 0.07, kappa, 20)
    got = conf.radii(s, tp, tr, group, prior)
    for g in (0, 1):
        rows = group == g
        want = reference_radii(s[rows], tp[rows], tr[rows], prior, LEVELS, 0.07, kappa, 20)
        np.testing.assert_allclose(got[:, rows], want, rtol=1e-12)


@pytest.mark.parametrize("kappa", [0.0, 10.0])
def test_the_ellipses_are_nested_whatever_the_order_of_the_levels(kappa):
    """Levels one point apart, given out of order, each tracked on its own by a large step,
    with and without the correction: at every prediction and step the higher level's radius
    is at least the lower's (without the nesting the 51 % radius falls below the 50 % one on
    this stream), and the result is the ascending order's."""
    levels = (0.95, 0.51, 0.5)
    s, tp, tr, _ = bursty_drifting_scene(3)
    prior = np.random.default_rng(7).exponential(2.0, (500, 12))
    one = np.zeros(tp.size, int)
    r = ScaleTracker(levels, eta=0.5, kappa=kappa).radii(s, tp, tr, one, prior)
    assert np.all(r[1] >= r[2]) and np.all(r[0] >= r[1])
    up = ScaleTracker(levels[::-1], eta=0.5, kappa=kappa).radii(s, tp, tr, one, prior)
    np.testing.assert_array_equal(r, up[::-1])
    # the correction judges the nested radius each prediction was given
    want = reference_radii(s, tp, tr, prior, levels[::-1], 0.5, kappa, 50)
    np.testing.assert_allclose(up, want, rtol=1e-12)


def test_a_prediction_never_sees_a_later_outcome():
    """Changing every score revealed after time T leaves the radii of predictions made by T
    unchanged bit for bit; the radii made later do change."""
    s, tp, tr = stream(400, seed=7, step=2)
    prior, _, _ = stream(50, seed=8)
    conf = ScaleTracker(LEVELS, 0.1, 10.0)
    before = conf.radii(s, tp, tr, np.zeros(400, int), prior)
    later = tr > 300
    s2 = s.copy()
    s2[later] = np.random.default_rng(9).exponential(20.0, s2[later].shape)
    after = conf.radii(s2, tp, tr, np.zeros(400, int), prior)
    made = tp <= 300
    np.testing.assert_array_equal(after[:, made], before[:, made])
    assert not np.array_equal(after[:, ~made], before[:, ~made])


def test_the_choice_on_held_out_streams_takes_either_kind():
    """Validation scenes: two long ones at the prior's scale and one short bursty one whose
    scale drifts (:func:`bursty_drifting_scene`). Met as a new scene, the tracker is nearer
    nominal than the rescaled sliding window, so it is chosen; each kind names its setting."""
    parts = [stream(400, h=12, seed=31), stream(400, h=12, seed=32),
             bursty_drifting_scene(40)[:3]]
    s = np.concatenate([p[0] for p in parts])
    tp = np.concatenate([p[1] for p in parts])
    tr = np.concatenate([p[2] for p in parts])
    scene = np.repeat([0, 1, 2], [400, 400, 180])
    window, tracker = AdaptiveConformal(LEVELS, 0.005, 100, 3), ScaleTracker(LEVELS)
    best, table = select_on_held_out_streams([window, tracker], s, tp, tr, scene)
    assert best == 1 and table[1].distance_mean < table[0].distance_mean
    assert tracker.setting == {"online_method": "scale_tracker", "online_eta": 0.05,
                               "online_kappa": 10.0, "online_prior_outcomes": 50}
    assert window.setting == {"online_method": "aci_window", "online_gamma": 0.005,
                              "online_window": 100, "online_rescale_after": 3}
    rep = tracker.coverage(s, tp, tr, scene, s[:100], clusters=scene)
    assert len(rep["online_coverage_50_ci95"]) == 2 and 0 < rep["online_radius_50"] < np.inf


def test_bad_input_is_named():
    s, tp, tr = stream(20)
    prior, _, _ = stream(30, seed=1)
    one = np.zeros(20, int)
    for bad in (0.0, 1.5, True, "x", float("nan")):
        with pytest.raises(ConformalError, match="eta: expected a number in \\(0, 1\\]"):
            ScaleTracker(LEVELS, bad)
    with pytest.raises(ConformalError, match="kappa: expected a number in \\[0, 100\\]"):
        ScaleTracker(LEVELS, 0.05, -1.0)
    with pytest.raises(ConformalError, match="prior_outcomes"):
        ScaleTracker(LEVELS, 0.05, 10.0, -1)
    with pytest.raises(ConformalError, match="levels"):
        ScaleTracker((0.5, 1.2))
    with pytest.raises(ConformalError, match="ScaleTracker.radii: t_revealed must be after"):
        ScaleTracker(LEVELS).radii(s, tp, tp, one, prior)
    with pytest.raises(ConformalError, match="prior"):
        ScaleTracker(LEVELS).radii(s, tp, tr, one, prior[:, :2])
    empty = prior.copy()
    empty[:, 1] = np.nan
    with pytest.raises(ConformalError, match="none at steps \\[1\\]"):
        ScaleTracker(LEVELS).radii(s, tp, tr, one, empty)
    with pytest.raises(ConformalError, match="positive quantile"):
        ScaleTracker(LEVELS).radii(s, tp, tr, one, np.zeros_like(prior))
