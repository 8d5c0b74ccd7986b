"""Issue 40's timing and reference rows: the first moving track row near the lead pedestrian,
delay statistics per speed, the true-state reference tracks and the track_state forecast."""

import numpy as np
import pandas as pd
import pytest

from blindspot.safety.evaluation import TRACK_STEPS, delay_stats, first_track_s, first_track_times
from blindspot.safety.oracle import true_state_tracks
from blindspot.safety.predict import TrackState, track_state_forecast


def test_first_moving_row_near_the_lead_pedestrian():
    truth = pd.DataFrame({"scene": "a", "frame": np.arange(5), "pedestrian": "p0",
                          "x_m": 2.0 - 0.14 * np.arange(5), "y_m": 10.0})
    tracks = pd.DataFrame({"group": "a", "frame": np.arange(5), "time_s": np.arange(5) * 0.1,
                           "x_m": truth.x_m + 0.2, "y_m": 10.0,
                           "confirmed": [False, True, True, True, True],
                           "moving": [False, False, True, True, True]})
    clutter = tracks.assign(x_m=5.0, moving=True, confirmed=True)     # far: never counts
    both, scenes = pd.concat([tracks, clutter]), np.array(["a", "b"])
    t = first_track_s(both, truth, scenes)
    assert t[0] == pytest.approx(0.2) and np.isnan(t[1])
    # born: its first row; confirmed: its first confirmed row (the clutter is never near)
    assert first_track_s(both, truth, scenes, step="born")[0] == pytest.approx(0.0)
    assert first_track_s(both, truth, scenes, step="confirmed")[0] == pytest.approx(0.1)
    # 0.15 m of radius: the track 0.2 m off the child never counts
    assert np.isnan(first_track_s(both, truth, scenes, radius_m=0.15)).all()


def test_first_track_times_match_each_step_alone():
    rng = np.random.default_rng(3)
    n = 60
    truth = pd.DataFrame({"scene": np.repeat(["a", "b", "c"], 20),
                          "frame": np.tile(np.arange(20), 3), "pedestrian": "p0",
                          "x_m": rng.normal(size=n), "y_m": rng.normal(size=n)})
    tracks = truth.rename(columns={"scene": "group"}).drop(columns="pedestrian").assign(
        time_s=lambda d: d.frame * 0.1, x_m=lambda d: d.x_m + rng.normal(0, 0.8, n),
        confirmed=rng.random(n) < 0.5, moving=rng.random(n) < 0.5)
    scenes = np.array(["c", "a", "b", "z"])
    both = first_track_times(tracks, truth, scenes)
    assert set(both) == set(TRACK_STEPS)
    near = np.hypot(tracks.x_m - truth.x_m, tracks.y_m - truth.y_m).to_numpy() <= 1.0
    rows = {"born": near, "confirmed": near & tracks.confirmed.to_numpy(),
            "moving": near & tracks.confirmed.to_numpy() & tracks.moving.to_numpy()}
    for step in TRACK_STEPS:                 # row by row, as the definition reads
        want = [tracks.time_s[rows[step] & (tracks.group == g).to_numpy()].min()
                if (rows[step] & (tracks.group == g).to_numpy()).any() else np.nan
                for g in scenes]
        np.testing.assert_array_equal(both[step], want)
        np.testing.assert_array_equal(both[step], first_track_s(tracks, truth, scenes, step=step))
    assert np.isnan(both["moving"][3])                       # a scene without tracks
    assert (both["born"][:3] <= both["confirmed"][:3]).all()
    for bad in (("moving", "moving"), (), ["moving"], ("fast",)):
        with pytest.raises(ValueError, match="first_track_times: steps: expected"):
            first_track_times(tracks, truth, scenes, steps=bad)
    with pytest.raises(ValueError, match="first_track_times: radius_m"):     # names the caller
        first_track_times(tracks, truth, scenes, radius_m=0.0)
    with pytest.raises(ValueError, match="first_track_times: tracks.*confirmed"):
        first_track_times(tracks.drop(columns="confirmed"), truth, scenes)


@pytest.mark.parametrize("kw, match", [({"step": "tentative"}, "step: expected one of"),
                                       ({"radius_m": 0.0}, "radius_m"),
                                       ({"radius_m": "1"}, "radius_m"),
                                       ({"lead": 3}, "lead: expected"),
                                       ({"scenes": "a"}, "scenes: expected"),
                                       ({"scenes": np.array([["a"]])}, "scenes: expected"),
                                       ({"scenes": np.array([1, 2])}, r"found 1 \(int\)"),
                                       ({"tracks": "drop confirmed"}, r"tracks.*confirmed"),
                                       ({"truth": "drop pedestrian"}, r"truth.*pedestrian")])
def test_first_track_s_refuses_bad_arguments(kw, match):
    truth = pd.DataFrame({"scene": "a", "frame": [0], "pedestrian": "p0", "x_m": 0.0,
                          "y_m": 0.0})
    tracks = pd.DataFrame({"group": "a", "frame": [0], "time_s": 0.0, "x_m": 0.0, "y_m": 0.0,
                           "confirmed": True})
    args = {"tracks": tracks, "truth": truth, "scenes": np.array(["a"])}
    for name, table, col in (("tracks", tracks, "confirmed"), ("truth", truth, "pedestrian")):
        if kw.get(name) == f"drop {col}":
            kw = {**kw, name: table.drop(columns=col)}
    args.update({k: kw.pop(k) for k in ("tracks", "truth", "scenes") if k in kw})
    with pytest.raises(ValueError, match="first_track_s.*" + match):     # names the caller
        first_track_s(args["tracks"], args["truth"], args["scenes"], **kw)
    # born needs no confirmed column
    assert first_track_s(tracks.drop(columns="confirmed"), truth, np.array(["a"]),
                         step="born")[0] == 0.0


def test_delay_stats_per_speed():
    s = delay_stats(np.array([0.1, 0.3, np.nan, 0.5]), np.array([10.0, 10.0, 20.0, 20.0]))
    assert s["median"] == pytest.approx(0.3) and s["n_never"] == 1
    assert s["by_speed_kmh"]["10"]["median"] == pytest.approx(0.2)
    assert s["by_speed_kmh"]["20"]["n_never"] == 1


def test_true_state_tracks_cover_every_frame_in_sight():
    f = np.arange(6)
    child = pd.DataFrame({"scene": "a", "frame": f, "time_s": f * 0.1, "pedestrian": "p0",
                          "x_m": 3.0 - 0.14 * f, "y_m": 8.0, "vx_mps": -1.4, "vy_mps": 0.0,
                          "occluded": [False, True, True, False, False, False],
                          "collision_time_s": 0.5})
    # a pedestrian that never collides and is hidden once the ego has passed: its frames in
    # sight before that are what the decision must not brake for (the row used to drop them)
    kerb = child.assign(pedestrian="p1", x_m=4.0, vx_mps=0.0, vy_mps=1.4,
                        occluded=[False, False, False, False, True, True],
                        collision_time_s=np.nan)
    tr = true_state_tracks(pd.concat([kerb, child]))
    assert tr.moving.all() and tr.confirmed.all() and not tr.coasting.any()
    by = {k: g.frame.tolist() for k, g in tr.groupby(["pedestrian", "track_id"])}
    # the child's glimpse and its emergence are two tracks; ids unique within the scene
    assert by == {("p0", 0): [0], ("p0", 1): [3, 4, 5], ("p1", 2): [0, 1, 2, 3]}
    assert tr[tr.pedestrian == "p0"].vx_mps.eq(-1.4).all()
    np.testing.assert_allclose(tr.cov_xx, 0.01)
    np.testing.assert_allclose(tr.cov_vxvx, 0.04)


def test_true_state_tracks_split_at_gaps_and_number_per_scene():
    f = np.arange(5)
    walker = pd.DataFrame({"scene": "b", "frame": f, "time_s": f * 0.1, "pedestrian": "p0",
                           "x_m": 3.0, "y_m": 8.0 + 0.14 * f, "vx_mps": 0.0, "vy_mps": 1.4,
                           "occluded": False, "collision_time_s": np.nan})
    gappy = walker.assign(scene="c").drop(index=2)            # frame 2 missing: two tracks
    other = walker.assign(pedestrian="p1")                    # a second pedestrian in scene b
    shuffled = pd.concat([gappy, other, walker]).sample(frac=1.0, random_state=0)
    tr = true_state_tracks(shuffled)
    by = {k: g.frame.tolist() for k, g in tr.groupby(["group", "pedestrian", "track_id"])}
    assert by == {("b", "p0", 0): [0, 1, 2, 3, 4], ("b", "p1", 1): [0, 1, 2, 3, 4],
                  ("c", "p0", 0): [0, 1], ("c", "p0", 1): [3, 4]}
    cat = true_state_tracks(shuffled.astype({"scene": "category", "pedestrian": "category"}))
    assert sorted(map(tuple, cat[["track_id", "frame"]].to_numpy().tolist())) == \
        sorted(map(tuple, tr[["track_id", "frame"]].to_numpy().tolist()))


def test_true_state_tracks_check_their_input():
    row = {"scene": ["a"], "pedestrian": "p0", "frame": 0, "time_s": 0.0, "x_m": 0.0,
           "y_m": 0.0, "vx_mps": 0.0, "vy_mps": 0.0}
    with pytest.raises(ValueError, match=r"truth: missing columns \['occluded'\]"):
        true_state_tracks(pd.DataFrame(row))
    with pytest.raises(ValueError, match="occluded: expected booleans, found dtype"):
        true_state_tracks(pd.DataFrame({**row, "occluded": ["False"]}))
    with pytest.raises(ValueError, match="more than one row per"):
        true_state_tracks(pd.concat([pd.DataFrame({**row, "occluded": False})] * 2))
    with pytest.raises(TypeError, match="expected a pandas DataFrame, found dict"):
        true_state_tracks({**row, "occluded": False})
    with pytest.raises(ValueError, match="vel_std_mps"):
        true_state_tracks(pd.DataFrame(), vel_std_mps=0.0)
    with pytest.raises(ValueError, match="pos_std_m"):
        true_state_tracks(pd.DataFrame(), pos_std_m=0.0)
    empty = true_state_tracks(pd.DataFrame({**row, "occluded": False}).iloc[:0])
    assert empty.empty and empty.track_id.dtype == np.int64


def test_track_state_forecasts_the_filtered_state():
    from blindspot.traj.baselines import KalmanCV

    class Scaled:                                   # a calibrated Kalman: base, scale, options
        base = KalmanCV(dt=0.1, process_psd=0.5, meas_std=0.15)
        scale = np.ones(10)
        options = {}
    rows = pd.DataFrame({"x_m": [2.0], "y_m": [8.0], "vx_mps": [-1.4], "vy_mps": [0.0],
                         "cov_xx": [0.01], "cov_xy": [0.0], "cov_yy": [0.01],
                         "cov_vxvx": [0.04], "cov_vxvy": [0.0], "cov_vyvy": [0.04]})
    fc = track_state_forecast(TrackState(Scaled()), rows, 10)
    np.testing.assert_allclose(fc.mean[0, -1], [2.0 - 1.4 * 1.0, 8.0], atol=1e-9)
    # variance grows as P_xx + t^2 P_vv + process noise + R: at 1 s at least 0.01 + 0.04
    assert fc.cov[0, -1, 0, 0] > 0.05
