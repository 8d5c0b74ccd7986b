"""The scene you can watch (issue 44): a tiny driving scene rendered as a GIF (PillowWriter: the
path that works without ffmpeg), an .mp4 asked for without ffmpeg falling back to the GIF, the
90 % ellipse, the still frame at the AEB request."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from blindspot.report import animation
from blindspot.report.animation import (Movie, decision_frames, driving_movie, ellipse_axes,
                                        key_frame, render_movie, render_still)

N = 8


def tiny_scene() -> Movie:
    """8 frames at 0.1 s: an ego car driving +y at 8 m/s, a parked car, a child crossing from
    x = 2 m at y = 12 m, its points and track, a predicted path, the warning at frame 3 and the
    AEB request at frame 5, a range-Doppler map every other frame."""
    f = np.arange(N)
    t = f * 0.1
    ego_y = 8.0 * t
    truth = pd.DataFrame({"frame": f, "time_s": t, "ego_x_m": 0.0, "ego_y_m": ego_y,
                          "ego_yaw_deg": 0.0, "pedestrian": "p0", "x_m": 2.0 - 1.4 * t,
                          "y_m": 12.0})
    rng = np.random.default_rng(0)
    pts = pd.concat([
        pd.DataFrame({"frame": f, "x_m": truth.x_m + rng.normal(0, 0.05, N), "y_m": 12.0,
                      "static": False}),
        pd.DataFrame({"frame": np.repeat(f, 3), "x_m": 2.8, "y_m": np.tile([9.0, 10.0, 11.0], N),
                      "static": True})], ignore_index=True)
    tracks = pd.DataFrame({"frame": f, "track_id": 3, "x_m": truth.x_m, "y_m": 12.0,
                           "confirmed": f >= 2, "moving": f >= 2})
    steps = np.arange(1, 11)
    pred = pd.concat([pd.DataFrame({
        "frame": k, "track_id": 3, "step": steps, "t_ahead_s": 0.1 * steps,
        "x_m": truth.x_m[k] - 0.14 * steps, "y_m": 12.0, "cov_xx": 0.01 * steps,
        "cov_xy": 0.002 * steps, "cov_yy": 0.004 * steps}) for k in range(2, N)])
    rd = {"frame": np.arange(0, N, 2), "power": rng.exponential(1.0, (N // 2, 16, 8)),
          "range_axis_m": np.arange(16) * 0.5, "velocity_axis_mps": np.linspace(-4, 3, 8)}
    car = [[2.0, 9.0], [3.6, 9.0], [3.6, 11.5], [2.0, 11.5]]
    outcomes = pd.DataFrame({"scene": ["s"], "input": ["tracker"], "predictor": ["kalman"],
                             "warn_frame": [3], "aeb_frame": [5], "extra": [1.0]})
    return driving_movie("tiny", truth, [car], pts, tracks, pred,
                         decision_frames(outcomes, "s", predictor="kalman"), rd)


def test_a_tiny_scene_renders_as_a_gif_with_every_frame(tmp_path):
    movie = tiny_scene()
    assert list(movie.decisions.frame[movie.decisions.aeb]) == [5, 6, 7]
    out = render_movie(movie, tmp_path / "tiny.gif", fps=5, dpi=40)
    assert out == tmp_path / "tiny.gif"
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames == N
    assert not [p for p in tmp_path.iterdir() if p.name != "tiny.gif"]   # no temporary left


def test_an_mp4_without_ffmpeg_is_written_as_the_gif(tmp_path, monkeypatch):
    from matplotlib.animation import FFMpegWriter

    monkeypatch.setattr(FFMpegWriter, "isAvailable", classmethod(lambda cls: False))
    out = render_movie(tiny_scene(), tmp_path / "tiny.mp4", fps=5, dpi=30)
    assert out.suffix == ".gif" and out.is_file() and not (tmp_path / "tiny.mp4").exists()


def test_an_mp4_where_ffmpeg_exists(tmp_path):
    from matplotlib.animation import FFMpegWriter

    if not FFMpegWriter.isAvailable():
        pytest.skip("ffmpeg not installed: the GIF path is the one tested")
    out = render_movie(tiny_scene(), tmp_path / "tiny.mp4", fps=5, dpi=30)
    assert out.suffix == ".mp4" and out.stat().st_size > 1000


def test_the_still_shows_the_frames_after_the_aeb_request(tmp_path):
    movie = tiny_scene()
    assert key_frame(movie) == 7                       # two frames after the request at 5
    out = render_still(movie, key_frame(movie), tmp_path / "still.png", dpi=40)
    with Image.open(out) as im:
        assert im.format == "PNG"


def test_the_90_percent_ellipse_axes_are_the_covariance_eigenvectors():
    cov = np.array([[2.0, 0.6], [0.6, 1.0]])
    w, h, ang = ellipse_axes(*(np.float64(v) for v in (cov[0, 0], cov[0, 1], cov[1, 1])))
    vals, vecs = np.linalg.eigh(cov)
    assert np.isclose(w, 2 * np.sqrt(animation.CHI2_2DOF_90 * vals[1]))
    assert np.isclose(h, 2 * np.sqrt(animation.CHI2_2DOF_90 * vals[0]))
    major = vecs[:, 1]
    assert np.isclose(abs(np.cos(np.radians(ang)) * major[0] + np.sin(np.radians(ang)) * major[1]),
                      1.0)
    from scipy.stats import chi2

    assert np.isclose(animation.CHI2_2DOF_90, chi2.ppf(0.9, 2))


def test_outcomes_without_the_columns_give_no_decision():
    assert decision_frames(pd.DataFrame({"scene": ["s"]}), "s", predictor="kalman") == (None,
                                                                                          None)
    assert decision_frames(None, "s", predictor="kalman") == (None, None)
