"""Doppler-first tracks (issue 40): a new track starts with the velocity its Doppler allows,
confirms in two frames when its radial speeds say "moving", and is classed moving from then on;
a static object (compensated Doppler ~0) keeps the M-of-N rule and a zero-mean start."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from blindspot.track import TrackerConfig, track_points
from blindspot.track.moving import (doppler_motion_evidence, doppler_motion_log_ratio,
                                    moving_tracks)
from tests.conftest import REPO_ROOT

DT = 0.1


def config(**changes) -> TrackerConfig:
    """gnn_cv.yaml with the Doppler-first keys off unless ``changes`` set them."""
    cfg = TrackerConfig.from_mapping(OmegaConf.load(REPO_ROOT / "conf" / "tracker" / "gnn_cv.yaml"))
    off = dict(init_doppler_std_mps=None, init_doppler_along_std_mps=None,
               doppler_confirm_log_ratio=None)
    return dataclasses.replace(cfg, **{**off, **changes})


def walker(v_xy, doppler, n_frames=4, start=(2.0, 10.0), n_points=3):
    """One object per frame moving at v_xy from ``start``, seen from a radar at the origin,
    each point with compensated radial speed ``doppler`` (None: the true u.v)."""
    rows = []
    for f in range(n_frames):
        xy = np.asarray(start) + f * DT * np.asarray(v_xy)
        u = xy / np.hypot(*xy)
        d = float(u @ np.asarray(v_xy)) if doppler is None else doppler
        for k in range(n_points):
            rows.append({"frame": f, "time_s": f * DT, "x_m": xy[0] + 0.01 * k, "y_m": xy[1],
                         "velocity_over_ground_mps": d, "sensor_x_m": 0.0, "sensor_y_m": 0.0})
    return pd.DataFrame(rows)


def test_a_new_track_starts_with_the_velocity_its_doppler_allows():
    s0, sd, n = 1.5, 0.3, 3
    pts = walker((-1.4, 0.0), doppler=-0.8, n_frames=1)
    tr = track_points(pts, config(init_doppler_std_mps=sd))
    xy = np.array([2.01, 10.0])
    u = xy / np.hypot(*xy)
    expect = s0 ** 2 * u * -0.8 / (s0 ** 2 + sd ** 2 / n)        # Kalman update of N(0, s0^2 I)
    np.testing.assert_allclose(tr[["vx_mps", "vy_mps"]].to_numpy()[0], expect, rtol=1e-9)
    # the radial variance shrinks to ~sd^2 / n, the tangential one stays the prior's
    pv = np.array([[tr.cov_vxvx[0], tr.cov_vxvy[0]], [tr.cov_vxvy[0], tr.cov_vyvy[0]]])
    t = np.array([-u[1], u[0]])
    assert u @ pv @ u == pytest.approx(1 / (1 / s0 ** 2 + n / sd ** 2))
    assert t @ pv @ t == pytest.approx(s0 ** 2)
    # without the key, or with a static Doppler, the start is at rest as before
    assert np.allclose(track_points(pts, config())[["vx_mps", "vy_mps"]], 0.0)
    still = track_points(walker((0.0, 0.0), doppler=0.0, n_frames=1), config(init_doppler_std_mps=sd))
    assert np.allclose(still[["vx_mps", "vy_mps"]], 0.0)


def test_a_doppler_consistent_walker_confirms_in_two_frames_a_static_object_in_three():
    cfg = config(init_doppler_std_mps=0.3, doppler_confirm_log_ratio=float(np.log(100)))
    # a child 4 m ahead and 2 m right walking toward the lane: radial speed about -0.6 m/s
    child = track_points(walker((-1.4, 0.0), None, start=(2.0, 4.0)), cfg)
    assert child.groupby("frame").confirmed.any().tolist() == [False, True, True, True]
    kerb = track_points(walker((0.0, 0.0), 0.0, start=(4.5, 8.0)), cfg)
    assert kerb.groupby("frame").confirmed.any().tolist() == [False, False, True, True]
    # without the key the walker waits for M-of-N too
    slow = track_points(walker((-1.4, 0.0), None, start=(2.0, 4.0)), config())
    assert slow.groupby("frame").confirmed.any().tolist() == [False, False, True, True]


def test_doppler_motion_evidence_pools_the_last_window_hits_and_holds_through_coasting():
    t = pd.DataFrame({"group": "g", "track_id": 0, "frame": np.arange(5),
                      "n_points": [2, 3, 0, 1, 4], "doppler_mps": [0.5, -0.1, np.nan, 0.4, 0.2]})
    ev = doppler_motion_evidence(t, 0.3, window=2)
    expect = [doppler_motion_log_ratio([2], [0.5], 0.3),
              doppler_motion_log_ratio([2, 3], [0.5, -0.1], 0.3),
              doppler_motion_log_ratio([2, 3], [0.5, -0.1], 0.3),      # coasting: held
              doppler_motion_log_ratio([3, 1], [-0.1, 0.4], 0.3),
              doppler_motion_log_ratio([1, 4], [0.4, 0.2], 0.3)]
    np.testing.assert_allclose(ev, expect)
    # the statistic: z^2 / 2 of the pooled mean, z = sum n d / (std sqrt(sum n))
    assert doppler_motion_log_ratio([2, 3], [0.5, -0.1], 0.3) == pytest.approx(
        0.5 * ((1.0 - 0.3) / (0.3 * np.sqrt(5))) ** 2)


def test_doppler_first_classes_a_young_uncertain_track_moving():
    f = np.arange(3)
    t = pd.DataFrame({"group": "g", "track_id": 0, "frame": f, "vx_mps": -1.0, "vy_mps": 0.0,
                      "cov_vxvx": 1.0, "cov_vxvy": 0.0, "cov_vyvy": 1.0,
                      "confirmed": [False, True, True], "n_points": 3,
                      "doppler_mps": -0.6})
    assert not moving_tracks(t, 0.5).any()                 # chi2 = 1 < 9.21: not yet
    m = moving_tracks(t, 0.5, doppler_first_log_ratio=float(np.log(100)), doppler_std_mps=0.3)
    assert m.tolist() == [False, True, True]
    # a static object's zero Doppler does not pass
    z = moving_tracks(t.assign(doppler_mps=0.02), 0.5, doppler_first_log_ratio=float(np.log(100)),
                      doppler_std_mps=0.3)
    assert not z.any()


def test_the_context_prior_turns_the_radial_speed_into_a_crossing_speed():
    """With the velocity prior narrow along the road (the boresight), a child 10 m ahead and
    2 m beside the lane, whose Doppler shows only 0.27 m/s of its 1.4 m/s crossing, starts
    moving across the road at the posterior the two allow, several times the isotropic
    prior's start, and hardly along it."""
    xy = np.array([2.01, 10.0])
    v = np.array([-1.4, 0.0])
    pts = walker(v, doppler=None, n_frames=1, start=(2.0, 10.0), n_points=3).assign(
        sensor_heading_deg=0.0)
    iso = track_points(pts, config(init_doppler_std_mps=0.3))
    ctx = track_points(pts, config(init_doppler_std_mps=0.3, init_doppler_along_std_mps=0.2))
    u = xy / np.hypot(*xy)
    d = float(pts.velocity_over_ground_mps.iloc[0])
    pv = np.diag([1.5 ** 2, 0.2 ** 2])
    expect = pv @ u * d / (u @ pv @ u + 0.3 ** 2 / 3)
    np.testing.assert_allclose(ctx[["vx_mps", "vy_mps"]].to_numpy()[0], expect, rtol=1e-6)
    assert ctx.vx_mps[0] < 2.5 * iso.vx_mps[0] < 0          # several times the radial start
    assert abs(ctx.vy_mps[0]) < 0.1
