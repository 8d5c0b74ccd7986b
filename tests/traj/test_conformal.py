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


def reference_radii(scores, tp, tr, prior, levels, gamma, window, rescale_after=0):
    """Straight from Gibbs & Candès 2021 and split conformal, one prediction and one step at a
    time: before predicting at t, the outcomes of step k with reveal time <= t not yet seen move
    step k's a once by gamma (alpha - their share outside), NaN steps skipped; the radius is the
    ceil((1 - a)(M + 1))-th smallest of the M finite scores among step k's last ``window``
    revealed (``window`` evenly spaced prior rows first), +inf beyond M, 0 for 1 - a <= 0 (a
    rank within 1e-9 of a whole number is that number). ``tr`` (N,) or (N, H). With
    ``rescale_after`` k: once step k's window holds k own finite scores, its prior scores are
    multiplied by median(own) / median(prior rows kept), unless that median is 0."""
    n, h = scores.shape
    tr = np.broadcast_to(np.asarray(tr)[:, None], (n, h)) if np.ndim(tr) == 1 else tr
    alpha = 1 - np.asarray(levels)
    out = np.zeros((len(levels), n, h))
    a = np.tile(alpha[:, None], (1, h))
    if len(prior) > window:
        prior = prior[[k * len(prior) // window for k in range(window)]]
    seen = [set() for _ in range(h)]
    pools = [[("prior", v) for v in prior[:, k]] for k in range(h)]
    last_t = None
    for i in np.argsort(tp, kind="stable"):
        if tp[i] != last_t:                     # a new prediction time: reveal, then one step
            for k in range(h):
                new = [j for j in np.argsort(tr[:, k], kind="stable")
                       if tr[j, k] <= tp[i] and j not in seen[k]]
                errs = [scores[j, k] > out[:, j, k] for j in new if not np.isnan(scores[j, k])]
                if errs:
                    a[:, k] += gamma * (alpha - np.mean(errs, axis=0))
                seen[k].update(new)
                pools[k] += [("own", scores[j, k]) for j in new]
            last_t = tp[i]
        for k in range(h):
            recent = pools[k][-window:]
            own = [v for w, v in recent if w == "own" and not np.isnan(v)]
            ratio = 1.0
            prior_median = np.nanmedian(prior[:, k]) if len(prior) else np.nan
            if rescale_after and len(own) >= rescale_after and prior_median > 0:
                ratio = np.median(own) / prior_median
            values = np.array([v * ratio if w == "prior" else v for w, v in recent])
            finite = np.sort(values[~np.isnan(values)])
            for li in range(len(levels)):
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


def test_step_by_step_reveals_and_the_rescaled_prior_equal_the_reference():
    """Each step revealed at its own time (steps of one prediction known at different times,
    several predictions per time, NaN steps), with and without the rescaled prior, a prior
    whose median is 0 (no rescale) and none at all with a window longer than the stream: the
    batched recursion equals the one-at-a-time reference."""
    rng = np.random.default_rng(21)
    n, h = 150, 4
    tp = np.sort(rng.integers(0, 70, n))
    tr = tp[:, None] + 1 + np.arange(h) * rng.integers(1, 4, (n, 1))   # step k later than k-1
    s = rng.exponential(2.0, (n, h)) * np.where(np.arange(n) > 60, 7.0, 1.0)[:, None]
    s[rng.random((n, h)) < 0.05] = np.nan
    prior = rng.exponential(2.0, (40, h))
    zero_median = np.where(np.arange(40)[:, None] < 25, 0.0, prior)     # step medians 0
    cases = [(0.0, 20, 0, prior), (0.05, 30, 3, prior), (0.02, 15, 1, prior),
             (0.3, 10, 5, prior), (0.05, 30, 3, zero_median), (0.05, 500, 2, prior[:0])]
    for gamma, window, k, p in cases:
        got = AdaptiveConformal(LEVELS, gamma, window, k).radii(s, tp, tr, np.zeros(n, int), p)
        want = reference_radii(s, tp, tr, p, LEVELS, gamma, window, k)
        np.testing.assert_allclose(got, want, rtol=1e-12)


def test_a_step_is_used_once_it_is_known_and_not_before():
    """Per-step reveal times: changing every step-k score known after T leaves every radius of
    the predictions made by T unchanged; changing only the first-step scores known by T, of
    predictions whose last step is still unknown at T, changes the first step's radii at T
    (the whole-future reveal would not yet have used them)."""
    n, h = 300, 3
    s, tp, _ = stream(n, h, seed=22)
    tr = tp[:, None] + 1 + 4 * np.arange(h)                    # steps known 1, 5, 9 later
    prior, _, _ = stream(40, h, seed=23)
    conf = AdaptiveConformal(LEVELS, 0.01, 30, 3)
    before = conf.radii(s, tp, tr, np.zeros(n, int), prior)
    t_cut = 150
    made = tp <= t_cut
    s2 = s.copy()
    s2[tr > t_cut] = 50.0
    after = conf.radii(s2, tp, tr, np.zeros(n, int), prior)
    np.testing.assert_array_equal(after[:, made], before[:, made])
    s3 = s.copy()
    early = (tr[:, 0] <= t_cut) & (tr[:, -1] > t_cut)          # step 0 known, step 2 not yet
    assert early.sum() >= 5
    s3[early, 0] = 50.0
    third = conf.radii(s3, tp, tr, np.zeros(n, int), prior)
    assert not np.array_equal(third[:, tp == t_cut, 0], before[:, tp == t_cut, 0])


def test_the_rescaled_prior_covers_a_short_scene_of_another_scale():
    """A scene whose errors are 8x the validation data's (ETH/UCY's eth is about 5x), over its
    first 100 predictions, before the window can have filled with its own outcomes: with the
    prior as it is, the 50 % ellipses cover about 30 % (chance: a d^2 of 8x the prior's median
    is inside only once the window's middle holds own scores); rescaled after 3 own outcomes,
    within 5 pp of 50 %, and the 90 % ones closer to nominal too. Off by default."""
    s, tp, tr = stream(150, seed=24, scale=np.full(150, 8.0))
    prior, _, _ = stream(100, seed=25)
    zeros = np.zeros(150, int)
    plain = AdaptiveConformal(LEVELS, 0.005, 100).radii(s, tp, tr, zeros, prior)
    scaled = AdaptiveConformal(LEVELS, 0.005, 100, 3).radii(s, tp, tr, zeros, prior)
    assert AdaptiveConformal(LEVELS).rescale_prior_after == 0
    first = slice(0, 100)
    c_plain = ellipse_hits(s[first], plain[:, first])
    c_scaled = ellipse_hits(s[first], scaled[:, first])
    assert c_plain[0] < 0.35
    assert c_scaled[0] == pytest.approx(0.5, abs=0.05)
    assert abs(c_scaled[1] - 0.9) < abs(c_plain[1] - 0.9)
    assert np.isfinite(scaled).all()


def test_the_cluster_bootstrap_widens_with_correlated_points():
    """Coverage intervals from the cluster bootstrap match the binomial standard error of the
    number of independent clusters: 2,000 points, 1,800 of them inside, give a 95 % interval
    about 2 x 1.96 sqrt(0.09 / 2000) = 0.026 wide; the same 2,000 points as 100 clusters of 20
    that are wholly in or out (90 in), 2 x 1.96 sqrt(0.09 / 100) = 0.118 (+-25 %)."""
    from blindspot.traj.conformal import cluster_bootstrap_coverage

    rng = np.random.default_rng(26)
    seen = np.ones((2000, 1), bool)
    alone = (rng.permutation(2000) < 1800)[None, :, None]
    lo, hi = cluster_bootstrap_coverage(alone, seen, np.arange(2000), n_boot=4000)[0]
    assert hi - lo == pytest.approx(2 * 1.96 * np.sqrt(0.09 / 2000), rel=0.25)
    assert lo < alone.mean() < hi
    groups = np.repeat(np.arange(100), 20)
    together = np.repeat(rng.permutation(100) < 90, 20)[None, :, None]
    lo, hi = cluster_bootstrap_coverage(together, seen, groups, n_boot=4000)[0]
    assert hi - lo == pytest.approx(2 * 1.96 * np.sqrt(0.09 / 100), rel=0.25)
    with pytest.raises(ConformalError, match="clusters"):
        cluster_bootstrap_coverage(together, seen, groups[:10])


def test_the_choice_on_held_out_streams_prefers_what_a_new_scene_needs():
    """Three validation scenes, one with errors 8x the others' and short: met as a new scene
    with the others as its prior, the plain window under-covers it (and ACI, pushing the level
    up, runs out of scores) while the rescaled prior does not, so the rescale is chosen; a
    window too small for the 95 % level (unbounded ellipses) is never chosen, however close it
    comes; ties go to the first candidate."""
    from blindspot.traj.conformal import select_on_held_out_streams

    parts = [stream(400, seed=31), stream(400, seed=32),
             stream(120, seed=33, scale=np.full(120, 8.0))]
    s = np.concatenate([p[0] for p in parts])
    tp = np.concatenate([p[1] for p in parts])
    tr = np.concatenate([p[2] for p in parts])
    scene = np.repeat([0, 1, 2], [400, 400, 120])
    plain, rescaled, tiny = (AdaptiveConformal(LEVELS, 0.005, 100),
                             AdaptiveConformal(LEVELS, 0.005, 100, 3),
                             AdaptiveConformal(LEVELS, 0.005, 10, 3))
    best, table = select_on_held_out_streams([plain, rescaled, tiny], s, tp, tr, scene)
    assert best == 1
    assert table[0].distance_mean > table[1].distance_mean and table[1].unbounded == 0
    assert table[2].unbounded > 0       # 10 scores cannot give a 95 % quantile
    assert table[0].distance_worst >= table[0].distance_mean
    assert select_on_held_out_streams([rescaled, rescaled], s, tp, tr, scene)[0] == 0
    with pytest.raises(ConformalError, match="two validation streams"):
        select_on_held_out_streams([plain], s, tp, tr, np.zeros(len(s), int))
    with pytest.raises(ConformalError, match="one set of levels"):
        select_on_held_out_streams([plain, AdaptiveConformal((0.5,))], s, tp, tr, scene)


def test_the_held_out_choice_is_scored_on_the_test_streams_with_every_val_score_as_prior():
    """held_out_choice_coverage (the ETH/UCY folds' and the simulated paths' one path): the
    choice is select_on_held_out_streams', the report the chosen ellipses' coverage of the
    test stream from all the val scores, with their setting and val distance; one candidate
    or one val stream means no choice (and no distance)."""
    from blindspot.traj.conformal import held_out_choice_coverage, select_on_held_out_streams

    parts = [stream(400, seed=41), stream(400, seed=42),
             stream(120, seed=43, scale=np.full(120, 8.0))]
    val = tuple(np.concatenate([p[k] for p in parts]) for k in range(3)) + (
        np.repeat([0, 1, 2], [400, 400, 120]),)
    s_test, tp_test, tr_test = stream(150, seed=44, scale=np.full(150, 6.0))
    test = (s_test, tp_test, tr_test, np.zeros(150, int))
    clusters = np.arange(150) // 10
    cands = [AdaptiveConformal(LEVELS, 0.005, 100), AdaptiveConformal(LEVELS, 0.005, 100, 3)]
    report, chosen = held_out_choice_coverage(cands, val, test, clusters=clusters)
    best, table = select_on_held_out_streams(cands, *val)
    assert chosen is cands[best] and best == 1
    assert report == {**chosen.coverage(*test, val[0], clusters=clusters), **chosen.setting,
                      "online_val_distance": table[best].distance_mean}
    # the metrics files keep this key order
    assert list(report) == [*chosen.coverage(*test, val[0], clusters=clusters),
                            *chosen.setting, "online_val_distance"]
    assert abs(report["online_coverage_90"] - 0.9) < \
        abs(cands[0].coverage(*test, val[0])["online_coverage_90"] - 0.9)
    alone, first = held_out_choice_coverage(cands[1:], val, test)
    assert first is cands[1] and "online_val_distance" not in alone
    assert "online_coverage_50_ci95" not in alone
    one_stream = val[:3] + (np.zeros(len(val[0]), int),)
    single, first = held_out_choice_coverage(cands, one_stream, test)
    assert first is cands[0] and "online_val_distance" not in single
    # val is checked also when there is no choice to make
    with pytest.raises(ConformalError, match="val: stream: expected"):
        held_out_choice_coverage(cands[:1], val[:3] + (np.zeros(5, int),), test)
    with pytest.raises(ConformalError, match="one set of levels"):
        held_out_choice_coverage([cands[0], AdaptiveConformal((0.5,))], one_stream, test)
    as_list = AdaptiveConformal(list(LEVELS), 0.005, 100, 3)      # levels kept as a list
    assert held_out_choice_coverage([as_list, cands[1]], val, test, clusters=clusters)[0] == report
    for bad, match in (((), "candidates"), ("aci", "candidates"), ([0.5], "candidates")):
        with pytest.raises(ConformalError, match=match):
            held_out_choice_coverage(bad, val, test)
    with pytest.raises(ConformalError, match="val: expected"):
        held_out_choice_coverage(cands, val[:3], test)
    with pytest.raises(ConformalError, match="test: expected"):
        held_out_choice_coverage(cands, val, list(test))


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
    with pytest.raises(ConformalError, match="row 2 step 1 has t_predicted 2, t_revealed 2"):
        early = np.tile(tp[:, None] + 1.0, (1, 3))
        early[2, 1] = 2
        conf.radii(s, tp, early, np.zeros(10, int), s)
    with pytest.raises(ConformalError, match="t_revealed"):
        conf.radii(s, tp, np.tile(tr[:, None], (1, 2)), np.zeros(10, int), s)
    for bad in [dict(levels=(0.5, 1.0)), dict(levels=(0.9, 0.901)), dict(gamma=-0.1),
                dict(window=0), dict(window=2.5), dict(window=True),
                dict(rescale_prior_after=-1), dict(rescale_prior_after=True),
                dict(rescale_prior_after=1.5)]:
        with pytest.raises(ConformalError):
            AdaptiveConformal(**{"levels": LEVELS, **bad})
