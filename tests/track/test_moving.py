"""moving_tracks: which of the tracker's tracks (every radar point, static world included) the
warning assesses: from a track's first confirmed frame above the speed on, causally."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.track.moving import moving_tracks


def _tracks():
    f = np.arange(6)
    walk = pd.DataFrame({"group": "s0", "track_id": 1, "frame": f,
                         "vx_mps": [0.0, 0.1, 0.3, 0.9, 1.4, 0.0],   # starts, walks, stops
                         "vy_mps": 0.0, "confirmed": [False, True, True, True, True, True]})
    walk.loc[0, "vx_mps"] = 3.0                                         # tentative: ignored
    car = pd.DataFrame({"group": "s0", "track_id": 2, "frame": f, "vx_mps": 0.05,
                        "vy_mps": -0.05, "confirmed": True})              # a parked car
    early = pd.DataFrame({"group": "s1", "track_id": 1, "frame": f, "vx_mps": 1.4,
                          "vy_mps": 0.0, "confirmed": [False, False, True, True, True, True]})
    return pd.concat([walk, car, early], ignore_index=True).assign(cov_vxvx=0.01, cov_vxvy=0.0,
                                                                   cov_vyvy=0.01)


def test_moving_from_first_confirmed_fast_frame_on_and_latched():
    t = _tracks()
    m = moving_tracks(t, 0.5)
    assert m[:6].tolist() == [False, False, False, True, True, True]   # stays moving at the kerb
    assert not m[6:12].any()                                            # the static world
    assert m[12:].tolist() == [False, False, True, True, True, True]   # not before confirmed


def test_row_order_does_not_matter():
    t = _tracks()
    perm = np.random.default_rng(0).permutation(len(t))
    np.testing.assert_array_equal(moving_tracks(t.iloc[perm], 0.5), moving_tracks(t, 0.5)[perm])


def test_fast_but_uncertain_is_not_moving():
    t = _tracks().assign(cov_vxvx=0.01, cov_vxvy=0.0, cov_vyvy=0.01)
    assert moving_tracks(t, 0.5).any()
    # 1.4 m/s with a 1 m/s standard deviation per axis: d2 = 1.96 < 9.21 (chi2, 2 dof, 0.99)
    assert not moving_tracks(t.assign(cov_vxvx=1.0, cov_vyvy=1.0), 0.5).any()


def test_missing_column_is_named():
    with pytest.raises(ValueError, match="vx_mps"):
        moving_tracks(_tracks().drop(columns="vx_mps"), 0.5)


def test_risk_table_scores_moving_rows_only():
    from blindspot.safety.predict import risk_table
    from blindspot.safety.risk import EgoShape
    from blindspot.traj.distribution import GaussianForecast

    class Fixed:                                    # a forecast at the ego's bumper, sure
        def predict_distribution(self, h, horizon):
            mean = np.zeros((len(h), horizon, 2))
            return GaussianForecast(mean, np.broadcast_to(0.01 * np.eye(2),
                                                          (len(h), horizon, 2, 2)).copy())

    t = _tracks().assign(x_m=0.0, y_m=0.0)
    t["moving"] = moving_tracks(t, 0.5)
    ego = t[["group", "frame"]].drop_duplicates().assign(ego_x_m=0.0, ego_y_m=-1.0,
                                                         ego_yaw_deg=0.0, ego_speed_mps=5.0)
    r = risk_table(t, ego, {"x": Fixed()}, horizon=5, dt_s=0.1, shape=EgoShape(1.8, 4.5),
                   margin_m=0.3, method="max_step", max_len=5, max_coast_s=None)
    assert len(r) == int(t.moving.sum()) and (r.p_collision > 0.9).all()


def _doppler_track(vx, vy, doppler, x=3.0, y=10.0, n=5):
    f = np.arange(8)
    return pd.DataFrame({"group": "s0", "track_id": 1, "frame": f, "x_m": x, "y_m": y,
                         "vx_mps": vx, "vy_mps": vy, "cov_vxvx": 0.01, "cov_vxvy": 0.0,
                         "cov_vyvy": 0.01, "confirmed": True, "n_points": n,
                         "doppler_mps": doppler})


def _ego():
    return pd.DataFrame({"group": "s0", "frame": np.arange(8), "ego_x_m": 0.0, "ego_y_m": 0.0})


def test_doppler_refutes_a_static_cluster_sliding_along_a_parked_car():
    # a cluster on a car 3 m aside, 10 m ahead, whose centroid slides at 1 m/s along y while its
    # points show 0 over-ground radial speed: u.v = 10 / sqrt(109) = 0.96 m/s predicted, 0
    # measured -> "static" wins by (0.96^2) / (2 (0.09 / 5 + 0.01)) = 16 per frame
    kw = dict(ego=_ego(), doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    assert not moving_tracks(_doppler_track(0.0, 1.0, 0.0), 0.5, **kw).any()
    # the same track whose Doppler agrees with its velocity is moving
    assert moving_tracks(_doppler_track(0.0, 1.0, 10 / np.sqrt(109)), 0.5, **kw).all()
    # without the Doppler test the sliding cluster passes (the old false activations)
    assert moving_tracks(_doppler_track(0.0, 1.0, 0.0), 0.5).all()


def test_boresight_crossing_is_not_refuted_by_its_zero_doppler():
    # a child crossing at boresight (x = 0, 10 m ahead) walks across the line of sight: u.v = 0,
    # its Doppler 0 too, llr = 0 every frame: the kinematics decide
    kw = dict(ego=_ego(), doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    assert moving_tracks(_doppler_track(1.4, 0.0, 0.0, x=0.0), 0.5, **kw).all()


def test_doppler_log_ratio_is_the_gaussian_mean_test():
    from blindspot.track.moving import doppler_log_ratio

    t = _doppler_track(0.0, 1.0, 0.4, x=0.0)          # u = +y, u.v = 1, s^2 = 0.09 / 5 + 0.01
    llr = doppler_log_ratio(t, np.zeros((8, 2)), 0.3)
    s2 = 0.09 / 5 + 0.01
    np.testing.assert_allclose(llr, (0.4**2 - 0.6**2) / (2 * s2))
    coasting = t.assign(n_points=0, doppler_mps=np.nan)
    assert (doppler_log_ratio(coasting, np.zeros((8, 2)), 0.3) == 0).all()


def _face_and_tracks():
    """A car parked with its lane-side face at x = 2 m from y = 0 to 4.5 m, hit every frame
    (static points), a cluster on it whose centroid slides along the face at 1 m/s with a
    confident velocity (what the kinematic test passes as the ego goes by), and a child who
    steps out of the gap behind the car at y = 5.25 m and walks into the lane at 1.4 m/s
    (Euro NCAP child, 5 km/h) with its own points static-looking (tangential to the radar)."""
    f = np.arange(30)
    ys = np.arange(0.0, 4.5 + 1e-9, 0.3)
    face = pd.DataFrame({"scene": "s0", "frame": np.repeat(f, len(ys)), "x_m": 2.0,
                         "y_m": np.tile(ys, len(f)), "static": True})
    slide = pd.DataFrame({"group": "s0", "track_id": 1, "frame": f, "x_m": 2.0,
                          "y_m": 0.1 * (f % 40), "vx_mps": 0.0, "vy_mps": 1.0})
    x = 2.5 - 0.14 * f
    child = pd.DataFrame({"group": "s0", "track_id": 2, "frame": f, "x_m": x, "y_m": 5.25,
                          "vx_mps": -1.4, "vy_mps": 0.0})
    own = pd.DataFrame({"scene": "s0", "frame": f, "x_m": x, "y_m": 5.25, "static": True})
    tracks = pd.concat([slide, child], ignore_index=True).assign(
        cov_vxvx=0.01, cov_vxvy=0.0, cov_vyvy=0.01, confirmed=True, n_points=3)
    return tracks, pd.concat([face, own], ignore_index=True), x


def test_static_evidence_removes_a_cluster_sliding_along_a_parked_car():
    tracks, points, x = _face_and_tracks()
    assert moving_tracks(tracks, 0.5).all()                 # kinematics alone: both move
    m = moving_tracks(tracks, 0.5, points=points, static_evidence_min=1, static_cell_m=0.5,
                      static_lag_frames=10)
    slide, child = m[:30], m[30:]
    assert not slide[10:].any()        # once the car's hits are 10 frames old: static
    # the child, 1 m clear of the car's face (x < 1), is moving whatever its own Doppler
    assert child[x < 1.0].all()
    assert np.flatnonzero(child)[0] <= 8 + 3                # within 11 frames of stepping out
    # off (0) is the stage's test without the grid
    assert moving_tracks(tracks, 0.5, points=points, static_evidence_min=0).all()


def test_a_track_with_its_own_radial_speed_is_not_held_back_by_the_car_s_old_hits():
    """static_exempt_log_ratio: a car's face (x = 2 m) seen since frame 0; from frame 15 a
    child steps out over it at 1.4 m/s (its points static-looking, tangential) with its own
    radial speed (-0.5 m/s, 3 points a frame, point spread 0.3 m/s: ln ratio 8.3 on its second
    row, above 4.6), a cluster sliding along the face with the static world's (0). The grid
    alone holds the child back while it stands on the face's old hits; with the exemption it
    is moving from its second row, and the sliding cluster is held back as before."""
    f = np.arange(40)
    ys = np.arange(0.0, 4.5 + 1e-9, 0.3)
    face = pd.DataFrame({"scene": "s0", "frame": np.repeat(f, len(ys)), "x_m": 2.0,
                         "y_m": np.tile(ys, len(f)), "static": True})
    fc = f[15:]
    x = 2.5 - 0.14 * (fc - 15)
    slide = pd.DataFrame({"group": "s0", "track_id": 1, "frame": f, "x_m": 2.0,
                          "y_m": 0.1 * f, "vx_mps": 0.0, "vy_mps": 1.0, "doppler_mps": 0.0})
    child = pd.DataFrame({"group": "s0", "track_id": 2, "frame": fc, "x_m": x, "y_m": 2.25,
                          "vx_mps": -1.4, "vy_mps": 0.0, "doppler_mps": -0.5})
    tracks = pd.concat([slide, child], ignore_index=True).assign(
        cov_vxvx=0.01, cov_vxvy=0.0, cov_vyvy=0.01, confirmed=True, n_points=3)
    kw = dict(points=face, static_evidence_min=1, static_cell_m=0.5, static_lag_frames=10)
    grid = moving_tracks(tracks, 0.5, **kw)
    exempt = moving_tracks(tracks, 0.5, static_exempt_log_ratio=4.6, **kw)
    on_slide, on_child = slice(0, 40), slice(40, None)
    np.testing.assert_array_equal(exempt[on_slide], grid[on_slide])
    assert not exempt[on_slide][10:].any()
    assert not grid[on_child][:5].any()                       # held back on the face's hits
    assert not exempt[on_child][0] and exempt[on_child][1:].all()
    with pytest.raises(ValueError, match="static_exempt_log_ratio"):
        moving_tracks(tracks, 0.5, static_exempt_log_ratio=0.0, **kw)
    with pytest.raises(ValueError, match="static_exempt_log_ratio"):     # grid off: checked too
        moving_tracks(tracks, 0.5, static_exempt_log_ratio="4.6")


def test_static_evidence_is_read_at_the_last_hit_of_a_coasting_track():
    # the sliding cluster loses its points at frame 20 on the car's face and coasts at its
    # filtered velocity, turned into the lane (-1.4 m/s in x, 1.4 m/s in y): its extrapolated
    # position leaves the car's static hits, but nothing the radar saw did
    tracks, points, x = _face_and_tracks()
    slide = tracks.track_id.to_numpy() == 1
    coast = slide & (tracks.frame.to_numpy() >= 20)
    f = tracks.frame.to_numpy() - 20
    tracks.loc[coast, "x_m"] = 2.0 - 1.4 * 0.1 * f[coast]
    tracks.loc[coast, "vx_mps"] = -1.4
    tracks.loc[coast, "n_points"] = 0
    kw = dict(points=points, static_evidence_min=1, static_cell_m=0.5, static_lag_frames=10)
    m = moving_tracks(tracks, 0.5, **kw)
    assert not m[slide & (tracks.frame.to_numpy() >= 10)].any()    # the car's hits are old
    # read at the extrapolated position (every row measured) the coasting rows pass
    assert m[~slide].any() and moving_tracks(tracks.assign(n_points=3), 0.5, **kw)[coast].any()
    # a child who coasts once clear of the car (x < 1 m at its last hit) stays moving
    child = ~slide
    gone = child & (tracks.frame.to_numpy() >= 15)
    m2 = moving_tracks(tracks.assign(n_points=np.where(gone, 0, 3)), 0.5, **kw)
    np.testing.assert_array_equal(m2[gone], m[gone])
    assert m2[gone].all()


def test_last_hit_rows():
    from blindspot.track.moving import last_hit_rows

    t = pd.DataFrame({"group": ["a"] * 7 + ["b"] * 3, "track_id": [1] * 5 + [2] * 2 + [1] * 3,
                      "frame": [0, 1, 2, 3, 4, 0, 1, 0, 1, 2],
                      "n_points": [0, 2, 0, 0, 1, 0, 0, 0, 0, 3]})
    # row 0 has no hit before it: itself; rows 2, 3 hold row 1; track a/2 and b/1 start
    # coasting and never take a hit from another track
    np.testing.assert_array_equal(last_hit_rows(t), [0, 1, 1, 1, 4, 5, 6, 7, 8, 9])
    perm = np.random.default_rng(1).permutation(len(t))
    inverse = np.argsort(perm)
    np.testing.assert_array_equal(last_hit_rows(t.iloc[perm]),
                                  inverse[last_hit_rows(t)[perm]])
    with pytest.raises(ValueError, match="n_points"):
        last_hit_rows(t.drop(columns="n_points"))


def test_marginal_doppler_ratio_is_the_bayes_factor_and_refutes_an_uncertain_young_track():
    from scipy.stats import norm

    from blindspot.track.moving import doppler_log_ratio

    # u = +y; a young track of 10 points on a parked car: filtered velocity (1.9, 0.6) m/s,
    # fast and significant for the kinematic test (d2 = 9.9 > 9.21), 0.6 m/s of it radial, with
    # variance 0.4 (m/s)^2 per axis; its Doppler says 0
    t = _doppler_track(1.9, 0.6, 0.0, x=0.0, n=10).assign(cov_vxvx=0.4, cov_vyvy=0.4)
    s0, s1 = 0.09 / 10, 0.09 / 10 + 0.4
    want = norm.logpdf(0.0, 0.6, np.sqrt(s1)) - norm.logpdf(0.0, 0.0, np.sqrt(s0))
    llr = doppler_log_ratio(t, np.zeros((8, 2)), 0.3, "marginal")
    np.testing.assert_allclose(llr, want)
    assert (llr < np.log(0.1)).all()
    # the common-variance form gives -0.44 per frame: the first frame passes and latches; the
    # marginal form (-2.35 per frame, an Occam term -1.9 of it) refutes from the first
    kw = dict(ego=_ego(), doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    assert moving_tracks(t, 0.5, **kw).all()
    assert not moving_tracks(t, 0.5, doppler_llr="marginal", **kw).any()
    # a confident velocity (P_v -> 0): the two forms are the same test
    sure = _doppler_track(0.0, 1.0, 0.4, x=0.0).assign(cov_vxvx=0.0, cov_vyvy=0.0)
    np.testing.assert_allclose(doppler_log_ratio(sure, np.zeros((8, 2)), 0.3, "marginal"),
                               doppler_log_ratio(sure, np.zeros((8, 2)), 0.3))
    coasting = t.assign(n_points=0, doppler_mps=np.nan)
    assert (doppler_log_ratio(coasting, np.zeros((8, 2)), 0.3, "marginal") == 0).all()
    with pytest.raises(ValueError, match="form"):
        doppler_log_ratio(t, np.zeros((8, 2)), 0.3, "exact")


def test_floor_lets_a_clutter_track_that_captures_a_child_be_classed_moving():
    # 8 frames of a cluster sliding along a parked car (u.v = 0.96 m/s predicted, Doppler 0:
    # "static" by 16.4 per frame, the sum at -131), then the track takes the detections of a
    # child walking at the same velocity with the matching Doppler (+16.4 per frame) for 6
    t = pd.concat([_doppler_track(0.0, 1.0, 0.0),
                   _doppler_track(0.0, 1.0, 10 / np.sqrt(109)).iloc[:6]],
                  ignore_index=True).assign(frame=np.arange(14))
    ego = pd.DataFrame({"group": "s0", "frame": np.arange(14), "ego_x_m": 0.0, "ego_y_m": 0.0})
    kw = dict(ego=ego, doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    assert not moving_tracks(t, 0.5, **kw).any()            # the clutter's sum is never repaid
    m = moving_tracks(t, 0.5, doppler_log_ratio_floor=np.log(0.01), **kw)
    assert not m[:8].any() and m[8:].all()                   # from the child's first frame
    with pytest.raises(ValueError, match="doppler_log_ratio_floor"):
        moving_tracks(t, 0.5, doppler_log_ratio_floor=-1.0, **kw)


@settings(max_examples=50, deadline=None)
@given(llr=st.lists(st.lists(st.floats(-20.0, 20.0), min_size=1, max_size=12), min_size=2,
                    max_size=4),
       floor=st.floats(-30.0, -2.4), shuffle=st.randoms(use_true_random=False))
def test_floored_sum_is_the_reflected_recursion(llr, floor, shuffle):
    # the closed form against max(floor, S + llr) frame by frame, S_0 = 0, for several tracks
    # of two groups with their rows shuffled, through the bound test of fast, sure tracks whose
    # per-frame ratio is set by their Doppler
    from blindspot.track.moving import doppler_log_ratio, moving_frames

    # u = +y, v = (0, 1): llr = (d^2 - (d - 1)^2) / (2 s^2) = (2d - 1) / (2 s^2)
    s2 = 0.09 / 5 + 1e-4
    parts = [pd.DataFrame({"group": f"g{i % 2}", "track_id": i, "frame": np.arange(len(x)),
                           "doppler_mps": (np.asarray(x) * 2 * s2 + 1) / 2})
             for i, x in enumerate(llr)]
    t = pd.concat(parts, ignore_index=True).assign(
        x_m=0.0, y_m=10.0, vx_mps=0.0, vy_mps=1.0, cov_vxvx=1e-4, cov_vxvy=0.0, cov_vyvy=1e-4,
        confirmed=True, n_points=5)
    order = list(range(len(t)))
    shuffle.shuffle(order)
    t = t.iloc[order].reset_index(drop=True)
    got = doppler_log_ratio(t, np.zeros((len(t), 2)), 0.3)
    ref = np.empty(len(t))
    for _, rows in t.groupby("track_id").groups.items():
        rows = t.loc[rows].sort_values("frame").index
        acc = 0.0
        for r in rows:
            acc = max(floor, acc + got[r])
            ref[r] = acc
    np.testing.assert_allclose(np.sort(got), np.sort(np.concatenate(llr)), atol=1e-6, rtol=1e-3)
    n = int(t.frame.max()) + 1
    ego = pd.DataFrame({"group": np.repeat(["g0", "g1"], n), "frame": np.tile(np.arange(n), 2),
                        "ego_x_m": 0.0, "ego_y_m": 0.0})
    bound = -2.3
    ok = moving_frames(t, 0.5, ego=ego, doppler_std_mps=0.3, doppler_log_ratio_min=bound,
                       doppler_log_ratio_floor=floor)
    far = np.abs(ref - bound) > 1e-6                                 # not on the boundary
    np.testing.assert_array_equal(ok[far], (ref > bound)[far])


def test_spread_ratio_is_the_ratio_of_two_scaled_chi_square_densities():
    from scipy.stats import chi2 as chi2_dist

    from blindspot.track.moving import doppler_spread_log_ratio

    # Q = (n - 1) s^2 ~ sigma^2 chi2(n - 1): the ratio of the densities of Q under the walker's
    # and the static object's sigma; one point or a coasting row carries no spread
    n = np.array([2, 3, 5, 8, 1, 0, 4])
    sd = np.array([0.1, 0.3, 0.8, 1.2, np.nan, np.nan, np.nan])
    t = pd.DataFrame({"n_points": n, "doppler_spread_mps": sd})
    got = doppler_spread_log_ratio(t, 0.27, 0.79)
    q, k = (n[:4] - 1) * sd[:4] ** 2, n[:4] - 1
    want = (chi2_dist.logpdf(q / 0.79**2, k) - 2 * np.log(0.79)
            - chi2_dist.logpdf(q / 0.27**2, k) + 2 * np.log(0.27))
    np.testing.assert_allclose(got[:4], want, rtol=1e-10)
    assert got[0] < 0 < got[3] and (got[4:] == 0).all()
    with pytest.raises(ValueError, match="static < walker"):
        doppler_spread_log_ratio(t, 0.8, 0.3)
    with pytest.raises(ValueError, match="doppler_spread_mps"):
        doppler_spread_log_ratio(t.drop(columns="doppler_spread_mps"), 0.27, 0.79)


def test_spread_refutes_a_tangential_slide_that_the_mean_doppler_cannot():
    # a cluster sliding at 1.4 m/s across the line of sight at boresight (x = 0, 10 m ahead):
    # its mean Doppler 0 agrees with the tangential velocity (llr 0), so the mean test keeps it;
    # its 3 points a frame spread 0.25 m/s (one rigid static object, the 0.27 m/s pooled spread
    # of driving_track.json), which "static" explains better each frame, by
    # 2 ln(0.27 / 0.79) + 0.25^2 (1 / 0.27^2 - 1 / 0.79^2) = -1.39: the per-frame test fails
    # from the second frame on (sum -2.78 < ln 0.1). A child crossing there, 3 points spread
    # 0.8 m/s (limbs), stays moving.
    from blindspot.track.moving import moving_frames

    kw = dict(ego=_ego(), doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    slide = _doppler_track(1.4, 0.0, 0.0, x=0.0, n=3).assign(doppler_spread_mps=0.25)
    child = slide.assign(doppler_spread_mps=0.8)
    assert moving_frames(slide, 0.5, **kw).all()                       # mean Doppler only
    per_frame = moving_frames(slide, 0.5, doppler_spread_std_mps=(0.27, 0.79), **kw)
    assert per_frame.tolist() == [True] + [False] * 7
    # moving_tracks latches its first moving frame (a walker stopping stays an object to watch)
    assert moving_tracks(slide, 0.5, doppler_spread_std_mps=(0.27, 0.79), **kw).all()
    assert moving_frames(child, 0.5, doppler_spread_std_mps=(0.27, 0.79), **kw).all()
    with pytest.raises(ValueError, match="doppler_spread_mps"):
        moving_tracks(slide.drop(columns="doppler_spread_mps"), 0.5,
                      doppler_spread_std_mps=(0.27, 0.79), **kw)


def _random_tracks(seed: int, n_tracks: int = 4) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Tracks of 2 groups with random positions, velocities, covariances, point counts and
    Dopplers (some rows coasting), rows shuffled; the radar's positions per group and frame."""
    rng = np.random.default_rng(seed)
    parts = []
    for i in range(n_tracks):
        k = int(rng.integers(1, 12))
        c = rng.uniform(0.01, 0.5, k)
        n = rng.integers(0, 4, k)
        parts.append(pd.DataFrame({
            "group": f"g{i % 2}", "track_id": i, "frame": np.arange(k) + int(rng.integers(0, 4)),
            "x_m": rng.uniform(-5, 5, k), "y_m": rng.uniform(3, 30, k),
            "vx_mps": rng.normal(0, 1.5, k), "vy_mps": rng.normal(0, 1.5, k),
            "cov_vxvx": c, "cov_vxvy": 0.3 * c * rng.uniform(-1, 1, k), "cov_vyvy": 1.5 * c,
            "confirmed": True, "n_points": n,
            "doppler_mps": np.where(n > 0, rng.normal(0, 0.8, k), np.nan)}))
    t = pd.concat(parts, ignore_index=True)
    t = t.iloc[rng.permutation(len(t))].reset_index(drop=True)
    frames = np.arange(20)
    ego = pd.DataFrame({"group": np.repeat(["g0", "g1"], 20), "frame": np.tile(frames, 2),
                        "ego_x_m": 0.0, "ego_y_m": np.tile(frames * 0.8, 2)})
    return t, ego


@pytest.mark.parametrize("form", ["common_variance", "marginal"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_doppler_terms_are_the_ratio_as_a_quadratic_in_the_velocity(form, seed):
    from blindspot.track.moving import doppler_evidence, doppler_log_ratio, doppler_log_ratio_terms

    t, ego = _random_tracks(seed)
    xy = t[["group", "frame"]].merge(ego, on=["group", "frame"], how="left")[
        ["ego_x_m", "ego_y_m"]].to_numpy()
    c, a, b = doppler_log_ratio_terms(t, xy, 0.3, form)
    v = t[["vx_mps", "vy_mps"]].to_numpy()
    own = c + np.einsum("ni,ni->n", a, v) - 0.5 * np.einsum("ni,nij,nj->n", v, b, v)
    np.testing.assert_allclose(own, doppler_log_ratio(t, xy, 0.3, form), rtol=1e-9, atol=1e-9)
    # "current": each row's track's Dopplers so far, each ratio taken at this row's velocity
    got = doppler_evidence(t, ego, 0.3, form, reference="current")
    for i in range(len(t)):
        past = t[(t.group == t.group[i]) & (t.track_id == t.track_id[i])
                 & (t.frame <= t.frame[i])]
        at_now = past.assign(vx_mps=t.vx_mps[i], vy_mps=t.vy_mps[i])
        pxy = at_now[["group", "frame"]].merge(ego, on=["group", "frame"], how="left")[
            ["ego_x_m", "ego_y_m"]].to_numpy()
        assert got[i] == pytest.approx(doppler_log_ratio(at_now, pxy, 0.3, form).sum(),
                                       rel=1e-9, abs=1e-9)
    with pytest.raises(ValueError, match="reference"):
        doppler_evidence(t, ego, 0.3, form, reference="latest")


def test_current_velocity_reference_forgives_a_corrected_velocity_but_not_a_sliding_one():
    # 8 frames of a cluster sliding along a parked car at (0, 1) m/s with Doppler 0 (refuted,
    # -16.4 a frame), then the track takes a child's detections: the filter's velocity turns to
    # the child's, (-1.4, 0.3) m/s, and its Doppler matches it. Judged frame by frame the
    # clutter's -131 is never repaid (no floor); judged against the velocity it has now, the
    # clutter's Dopplers (0) are asked only for u.(-1.4, 0.3) = -0.12 m/s (a child crossing
    # nearly across the line of sight) and the child is moving at once. The cluster that keeps
    # sliding stays refuted either way.
    u = np.array([3.0, 10.0]) / np.sqrt(109)
    child_v = np.array([-1.4, 0.3])
    t = pd.concat([_doppler_track(0.0, 1.0, 0.0),
                   _doppler_track(*child_v, float(u @ child_v)).iloc[:6]],
                  ignore_index=True).assign(frame=np.arange(14))
    ego = pd.DataFrame({"group": "s0", "frame": np.arange(14), "ego_x_m": 0.0, "ego_y_m": 0.0})
    kw = dict(ego=ego, doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    assert not moving_tracks(t, 0.5, **kw).any()
    m = moving_tracks(t, 0.5, doppler_reference="current", **kw)
    assert not m[:8].any() and m[8:].all()
    slide = _doppler_track(0.0, 1.0, 0.0)
    assert not moving_tracks(slide, 0.5, doppler_reference="current",
                             **{**kw, "ego": ego[ego.frame < 8]}).any()
    with pytest.raises(ValueError, match="doppler_reference"):
        moving_tracks(t, 0.5, doppler_reference="now", **kw)


def test_current_velocity_reference_is_late_for_a_pedestrian_who_stood_before_walking():
    # the price of reference "current" (why it is not the default): a pedestrian 3 m aside,
    # 10 m ahead, stands for 10 frames (velocity 0, Doppler 0), then walks at (-1, -1) m/s
    # with the matching Doppler. Frame by frame the standing frames ask nothing of the walking
    # velocity, and the walk is moving from its first frame; against the current velocity
    # every standing Doppler of 0 contradicts u.(-1, -1) = -1.24 m/s, and the track is not
    # moving within 6 frames of walking
    u = np.array([3.0, 10.0]) / np.sqrt(109)
    walk = np.array([-1.0, -1.0])
    stand = pd.concat([_doppler_track(0.0, 0.0, 0.0)] * 2).iloc[:10]
    t = pd.concat([stand, _doppler_track(*walk, float(u @ walk)).iloc[:6]],
                  ignore_index=True).assign(frame=np.arange(16))
    ego = pd.DataFrame({"group": "s0", "frame": np.arange(16), "ego_x_m": 0.0, "ego_y_m": 0.0})
    kw = dict(ego=ego, doppler_std_mps=0.3, doppler_log_ratio_min=np.log(0.1))
    frame = moving_tracks(t, 0.5, doppler_log_ratio_floor=np.log(0.01), **kw)
    assert not frame[:10].any() and frame[10:].all()
    assert not moving_tracks(t, 0.5, doppler_reference="current", **kw).any()


def test_confirmed_moving_reads_the_moving_column_only_where_it_exists():
    from blindspot.track.moving import confirmed_moving
    t = pd.DataFrame({"confirmed": [True, True, False], "moving": [True, False, True]})
    assert confirmed_moving(t).tolist() == [True, False, False]
    assert confirmed_moving(t.drop(columns="moving")).tolist() == [True, True, False]
    with pytest.raises(ValueError, match=r"missing columns \['confirmed'\]"):
        confirmed_moving(t.drop(columns="confirmed"))
