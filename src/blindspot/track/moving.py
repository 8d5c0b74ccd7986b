"""Which confirmed tracks are moving objects: the moving-object test of the driving chain.

A track is a moving object from its first frame whose filtered world-frame velocity is above a
speed, significantly non-zero (a chi-square test on the velocity covariance), not refuted by its
own Doppler (the summed log-likelihood ratio "moves as tracked" vs "static",
:func:`doppler_log_ratio`, optionally with the objects' Doppler spread,
:func:`doppler_spread_log_ratio`) and, per row, not standing on the static environment
(:func:`static_evidence`). The settings are the tracker's ``tracker.moving`` keys
(:func:`moving_test_settings`; until issue 42 ``warning.moving_*``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import chi2, norm

from blindspot.arrays import check_number
from blindspot.tables import check_columns
from blindspot.track.crossing import CrossingPrior, approach_z, crossing_evidence

__all__ = ["DOPPLER_LLR_FORMS", "DOPPLER_REFERENCES", "DOPPLER_FIRST_WINDOW",
           "doppler_motion_log_ratio", "doppler_motion_evidence", "doppler_log_ratio",
           "doppler_log_ratio_terms", "doppler_spread_log_ratio", "moving_tracks",
           "moving_frames", "velocity_chi2", "doppler_evidence", "moving_test_settings",
           "last_hit_rows", "coast_frames", "confirmed_moving", "track_static_evidence",
           "static_evidence"]

#: Forms of the Doppler log-likelihood ratio (:func:`doppler_log_ratio`).
DOPPLER_LLR_FORMS: tuple[str, ...] = ("common_variance", "marginal")
#: Measured rows of a track whose radial speeds the Doppler-first path pools
#: (:func:`doppler_motion_evidence`): 0.3 s at 10 frames/s, short enough that the radial speed
#: of a walker seen from a passing car changes little.
DOPPLER_FIRST_WINDOW = 3
#: Which velocity the Doppler evidence judges each Doppler against (:func:`doppler_evidence`):
#: the track's velocity at that frame, or the one it has now.
DOPPLER_REFERENCES: tuple[str, ...] = ("frame", "current")


def doppler_log_ratio(tracks: pd.DataFrame, ego_xy: np.ndarray, doppler_std_mps: float,
                      form: str = "common_variance") -> np.ndarray:
    """(N,) per row of ``tracks``: the log-likelihood ratio of its Doppler measurement between
    "the object moves with the track's filtered velocity" and "the object is static".

    The radar measures, per point, the ego-motion-compensated radial speed (the
    ``doppler_mps`` column, the median over the object's points; 0 for a static object up to
    noise). With the unit line of sight u from the radar (``ego_xy`` (N, 2), m, the radar's
    world position at the row's frame) to the track, the filtered velocity v (vx_mps, vy_mps)
    predicts the radial speed u.v with variance u^T P_v u; a point's own spread is
    ``doppler_std_mps``, so an object of n points has d ~ N(u.v, s^2) if moving and
    N(0, s^2) if static, s^2 = doppler_std^2 / n + u^T P_v u, and

        llr = (d^2 - (d - u.v)^2) / (2 s^2)

    (``form`` "common_variance": the Gaussian log-likelihood ratio of the two mean hypotheses
    with a common variance; Van Trees 1968, sec. 2.2). Near-tangential motion (a child crossing
    at boresight) predicts u.v ~ 0 and gets llr ~ 0: Doppler neither confirms nor refutes it,
    the kinematics decide. A static cluster whose centroid slides along a parked car as the ego
    passes shows a kinematic velocity with a radial part that its Doppler (~0) refutes: llr < 0.

    ``form`` "marginal": the static hypothesis keeps only the measurement spread,
    d ~ N(0, s0^2) with s0^2 = doppler_std^2 / n, while "moving" marginalises the velocity over
    the track's posterior, d ~ N(u.v, s1^2) with s1^2 = s0^2 + u^T P_v u:

        llr = -ln(s1 / s0) - (d - u.v)^2 / (2 s1^2) + d^2 / (2 s0^2)

    the per-frame marginal likelihood ratio of one Doppler measurement given the positions (the
    filter's velocity posterior uses positions only; Kass & Raftery 1995, JASA 90(430)). It
    carries an Occam term -ln(s1 / s0): a young track whose velocity is uncertain along the line
    of sight is refuted by a Doppler near 0, the clutter tracks born from two hits on different
    parts of a parked car, and a child crossing near boresight in its first frames too. Summed
    over frames it is not the Bayes factor of the Doppler sequence: the frames share one
    velocity, so their Dopplers are correlated under "moving" and the sequential predictive
    would pay the Occam term about once; the sum pays it every frame (a stricter test, which is
    what refutes the young clutter tracks). Rows without a measurement (coasting, no
    ``doppler_mps``) give 0 in both forms. Raises ValueError for another ``form`` or a
    ``doppler_std_mps`` that is not finite and > 0.
    """
    check_number(doppler_std_mps, "doppler_std_mps", gt=0.0, unit="m/s",
                 who="doppler_log_ratio")
    d, u, var0, var1, ok = _doppler_geometry(tracks, ego_xy, doppler_std_mps, form)
    uv = u[:, 0] * tracks.vx_mps.to_numpy(float) + u[:, 1] * tracks.vy_mps.to_numpy(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        if form == "common_variance":
            llr = (d ** 2 - (d - uv) ** 2) / (2 * var1)
        else:
            llr = (-0.5 * np.log(var1 / var0) - (d - uv) ** 2 / (2 * var1)
                   + d ** 2 / (2 * var0))
    return np.where(ok, llr, 0.0)


def _doppler_geometry(tracks: pd.DataFrame, ego_xy: np.ndarray, doppler_std_mps: float,
                      form: str) -> tuple[np.ndarray, ...]:
    """Per row: the Doppler d, the unit line of sight u (N, 2), s0^2, s1^2 of
    :func:`doppler_log_ratio` and whether the row has a Doppler measurement."""
    if form not in DOPPLER_LLR_FORMS:
        raise ValueError(f"form: expected one of {list(DOPPLER_LLR_FORMS)}, found {form!r}")
    n = tracks.n_points.to_numpy(float)
    d = tracks.doppler_mps.to_numpy(float)
    los = tracks[["x_m", "y_m"]].to_numpy(float) - np.asarray(ego_xy, float)
    rng = np.hypot(los[:, 0], los[:, 1])
    u = los / np.where(rng > 0, rng, 1.0)[:, None]
    pu = (tracks.cov_vxvx.to_numpy(float) * u[:, 0] ** 2
          + 2 * tracks.cov_vxvy.to_numpy(float) * u[:, 0] * u[:, 1]
          + tracks.cov_vyvy.to_numpy(float) * u[:, 1] ** 2)
    var0 = doppler_std_mps ** 2 / np.maximum(n, 1.0)        # s0^2, s1^2 of the docstring
    var1 = var0 + pu
    ok = (n > 0) & np.isfinite(d) & (rng > 0)
    return d, u, var0, var1, ok


def doppler_log_ratio_terms(tracks: pd.DataFrame, ego_xy: np.ndarray, doppler_std_mps: float,
                            form: str = "common_variance"
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each row's :func:`doppler_log_ratio` as a function of a velocity v (m/s, world frame):

        llr(v) = c + a . v - v^T B v / 2

    c (N,), a (N, 2) in s/m, B (N, 2, 2) in s^2/m^2: with d, u, s0^2, s1^2 of
    :func:`doppler_log_ratio` (the row's own line of sight and variances), the quadratic in v of
    (d^2 - (d - u.v)^2) /
    (2 s1^2) ("common_variance": c = 0) or of the "marginal" form (c = -ln(s1 / s0) - d^2 /
    (2 s1^2) + d^2 / (2 s0^2)); a = d u / s1^2 and B = u u^T / s1^2 in both. At the row's own
    filtered velocity it is :func:`doppler_log_ratio`; summed over a track's rows and evaluated
    at its latest velocity it is the evidence of all the track's Dopplers for the velocity it
    has now (:func:`doppler_evidence`, ``reference="current"``). Rows without a measurement
    give zeros. Raises ValueError for another ``form``."""
    d, u, var0, var1, ok = _doppler_geometry(tracks, ego_xy, doppler_std_mps, form)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = (np.zeros(len(d)) if form == "common_variance"
             else -0.5 * np.log(var1 / var0) - d ** 2 / (2 * var1) + d ** 2 / (2 * var0))
        a = (d / var1)[:, None] * u
        b = u[:, :, None] * u[:, None, :] / var1[:, None, None]
    return (np.where(ok, c, 0.0), np.where(ok[:, None], a, 0.0),
            np.where(ok[:, None, None], b, 0.0))


def doppler_motion_log_ratio(n_points, doppler_mps, doppler_std_mps: float) -> float:
    """The log-likelihood ratio, "a radial speed other than zero" against "static", of the
    median ego-motion-compensated radial speeds ``doppler_mps`` (k,) of k objects of one track
    with ``n_points`` (k,) points each (NaN speeds and empty objects left out): with each
    point's speed N(mu, doppler_std^2) about the object's radial speed mu, taken as one mu over
    the k frames, the generalised likelihood ratio of mu = its pooled estimate against mu = 0 is

        llr = z^2 / 2,  z = sum_k n_k d_k / (doppler_std sqrt(sum_k n_k))

    (Van Trees 1968, sec. 2.5; a static object, the parked cars' faces and the kerb, gives
    z ~ N(0, 1), so llr >= ln 100 = 4.6 in 1 % of its windows). One mu over a few frames: the
    window must be short, a track's radial speed changes as the ego passes. 0 without a
    speed."""
    n = np.asarray(n_points, float)
    d = np.asarray(doppler_mps, float)
    ok = np.isfinite(d) & (n > 0)
    if not ok.any():
        return 0.0
    z = (n[ok] * d[ok]).sum() / (doppler_std_mps * np.sqrt(n[ok].sum()))
    return float(0.5 * z * z)


def doppler_motion_evidence(tracks: pd.DataFrame, doppler_std_mps: float,
                            window: int) -> np.ndarray:
    """(N,) per row of ``tracks`` (columns group, track_id, frame, n_points, doppler_mps):
    :func:`doppler_motion_log_ratio` over the track's last ``window`` measured rows up to and
    including the row (a coasting row: its last measured ones; 0 before any). Vectorised: per
    track cumulative sums of n d and n over its measured rows, differenced ``window`` back.
    Any row order. Raises ValueError naming a missing column."""
    check_columns(tracks, {"group", "track_id", "frame", "n_points", "doppler_mps"}, "tracks",
                  note="the blindspot.track schema")
    order, key = _track_order(tracks)
    n = tracks.n_points.to_numpy(float)[order]
    d = tracks.doppler_mps.to_numpy(float)[order]
    ok = np.isfinite(d) & (n > 0)
    nd = np.where(ok, n * np.where(ok, d, 0.0), 0.0)
    nn = np.where(ok, n, 0.0)
    hit = pd.DataFrame({"k": key[ok], "nd": nd[ok], "nn": nn[ok]})
    g = hit.groupby("k", sort=False)
    c_nd, c_nn = g.nd.cumsum().to_numpy(), g.nn.cumsum().to_numpy()
    b_nd = pd.Series(c_nd).groupby(hit.k.to_numpy()).shift(window).fillna(0.0).to_numpy()
    b_nn = pd.Series(c_nn).groupby(hit.k.to_numpy()).shift(window).fillna(0.0).to_numpy()
    s_nd, s_nn = c_nd - b_nd, c_nn - b_nn
    with np.errstate(invalid="ignore", divide="ignore"):
        llr_hit = np.where(s_nn > 0, 0.5 * (s_nd / (doppler_std_mps * np.sqrt(s_nn))) ** 2, 0.0)
    llr = np.full(len(order), np.nan)
    llr[np.flatnonzero(ok)] = llr_hit
    llr = pd.Series(llr).groupby(key, sort=False).ffill().fillna(0.0).to_numpy()
    out = np.empty(len(order))
    out[order] = llr
    return out


def doppler_spread_log_ratio(tracks: pd.DataFrame, static_std_mps: float,
                             walker_std_mps: float) -> np.ndarray:
    """(N,) per row of ``tracks`` (columns n_points, doppler_spread_mps): the log-likelihood
    ratio of its object's Doppler spread between "a walker" and "static".

    The idea: a walker's limbs swing about its torso, so the ego-motion-compensated radial
    speeds of one walker's points in one frame may spread about their mean (micro-Doppler;
    V. C. Chen, "The Micro-Doppler Effect in Radar", Artech House 2011); a rigid static
    object's points share one radial speed up to the Doppler bin and the angle error. With the
    points' speeds Gaussian about their mean with standard deviation sigma, the residual sum of
    squares of n points, Q = (n - 1) s^2 (s = ``doppler_spread_mps``, the sample standard
    deviation), is sigma^2 chi-square with n - 1 degrees of freedom, and the ratio of its
    densities under sigma_w = ``walker_std_mps`` and sigma_s = ``static_std_mps`` is

        llr = (n - 1) ln(sigma_s / sigma_w) + Q / 2 (1 / sigma_s^2 - 1 / sigma_w^2)

    (the ratio of the two scaled chi-square densities of Q, the sufficient statistic of a
    Gaussian's variance with the mean unknown). It asks for no radial velocity, so it can refute
    a cluster sliding across the line of sight, which :func:`doppler_log_ratio` cannot. Caveats
    (README, "A micro-Doppler spread ratio"): the spread depends on the chain and on range (the
    simulated walker's comes mostly from its points within 5 m, and real walkers' points in
    TI's chains spread less than a static object's here); Doppler bins make an all-equal
    object (s = 0) pay the full (n - 1) ln(sigma_s / sigma_w). Rows with fewer than two points
    or no spread (coasting) give 0. Raises ValueError naming a missing column or standard
    deviations that are not 0 < static < walker."""
    check_columns(tracks, {"n_points", "doppler_spread_mps"}, "tracks",
                  note="the blindspot.track schema")
    if not (0.0 < static_std_mps < walker_std_mps):
        raise ValueError(f"static_std_mps, walker_std_mps: expected 0 < static < walker, found "
                         f"{static_std_mps!r}, {walker_std_mps!r}")
    dof = tracks.n_points.to_numpy(float) - 1.0
    q = dof * tracks.doppler_spread_mps.to_numpy(float) ** 2
    llr = (dof * np.log(static_std_mps / walker_std_mps)
           + 0.5 * q * (1.0 / static_std_mps ** 2 - 1.0 / walker_std_mps ** 2))
    return np.where((dof >= 1) & np.isfinite(q), llr, 0.0)


def moving_tracks(tracks: pd.DataFrame, speed_mps: float, probability: float = 0.99, *,
                  ego: pd.DataFrame | None = None, doppler_std_mps: float = 0.3,
                  doppler_log_ratio_min: float | None = None,
                  doppler_llr: str = "common_variance",
                  doppler_log_ratio_floor: float | None = None,
                  doppler_spread_std_mps: tuple[float, float] | None = None,
                  doppler_reference: str = "frame",
                  doppler_first_log_ratio: float | None = None,
                  crossing_prior: CrossingPrior | None = None,
                  crossing_log_ratio: float | None = None,
                  approach_probability: float | None = None,
                  approach_corridor_m: float = 5.0,
                  points: pd.DataFrame | None = None, static_evidence_min: int = 0,
                  static_cell_m: float = 0.5, static_lag_frames: int = 10,
                  static_exempt_log_ratio: float | None = None) -> np.ndarray:
    """(N,) bool per row of ``tracks`` (columns group, track_id, frame, vx_mps, vy_mps,
    cov_vxvx, cov_vxvy, cov_vyvy, confirmed; the tracker's world-frame filtered state): True
    from the track's first confirmed row on whose velocity is both fast, sqrt(vx^2 + vy^2) >
    ``speed_mps``, and significantly non-zero, v^T P_v^-1 v > the chi-square quantile of 2
    degrees of freedom at ``probability`` (a static object's filtered velocity is zero-mean
    Gaussian with covariance P_v, so it passes with probability 1 - ``probability`` per frame;
    the test of Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4, applied to the velocity), and,
    with ``ego`` and ``doppler_log_ratio_min`` given, whose Doppler does not refute that
    velocity: the sum over the track's frames so far of :func:`doppler_log_ratio` (of form
    ``doppler_llr``; a
    sequential probability ratio of "moves as tracked" against "static", Wald 1945) is above
    ``doppler_log_ratio_min`` (e.g. -ln 10: the track's own radial speeds make "static" ten
    times likelier than its kinematic velocity; with ``doppler_spread_std_mps`` = (static,
    walker) each frame's Doppler spread ratio :func:`doppler_spread_log_ratio` joins the
    sum, which needs the column doppler_spread_mps (both only with the Doppler test: without
    ``ego`` or ``doppler_log_ratio_min`` they are not used); with ``doppler_reference``
    "current" every Doppler so far is judged against the track's velocity now instead of its
    velocity then (:func:`doppler_evidence`); with ``doppler_log_ratio_floor`` the sum is
    held at or above that floor, max(floor, S + llr) each frame: Page's reflecting barrier
    (Page 1954, Biometrika 41), so the track of a clutter cluster that captures a pedestrian
    stepping out keeps no more than ``doppler_log_ratio_min - doppler_log_ratio_floor`` of
    "static" evidence against the pedestrian's Doppler). That needs the columns x_m, y_m, n_points,
    doppler_mps and ``ego`` (group, frame, ego_x_m, ego_y_m: the radar's world position).
    Causal (a car decides with the frames it has) and latched (a pedestrian stopping at the kerb
    stays a moving object), except that with ``points`` and ``static_evidence_min`` > 0 a row
    standing on the static environment is not moving: :func:`static_evidence` (cells of
    ``static_cell_m`` m, points of frames ``static_lag_frames`` and more before), read at the
    track's last measured row (:func:`last_hit_rows`; needs the column n_points: a clutter
    track coasting off a parked car's face at its filtered velocity has not left the car's
    static hits, nothing the radar saw moved there; :func:`track_static_evidence`), reaches
    ``static_evidence_min`` (a cluster sliding along a parked car's face, whose kinematic
    velocity passes the tests above while the ego passes the car; a pedestrian standing still
    on its own static hits for ``static_lag_frames`` frames is left out too). With
    ``static_exempt_log_ratio`` the grid does not hold back a row whose track's own radial
    speeds over its last :data:`DOPPLER_FIRST_WINDOW` measured rows make "moving" at least that
    many natural-log units likelier than "static" (:func:`doppler_motion_evidence`, point
    spread ``doppler_std_mps``): the cluster sliding along a car's face has the static world's
    radial speed, a child stepping out beside the car's corner (on the car's old hits) has its
    own. Raises ValueError
    naming a missing column, a row without an ego position, a ``doppler_llr`` not in
    DOPPLER_LLR_FORMS, or a ``doppler_log_ratio_floor`` above ``doppler_log_ratio_min``. With
    ``crossing_prior`` and ``crossing_log_ratio``, :func:`moving_frames`' crossing test makes
    rows moving too (before the latch and the grid); with ``approach_probability`` its approach
    test also makes a velocity significant, beside the chi-square test."""
    if static_exempt_log_ratio is not None:
        check_number(static_exempt_log_ratio, "static_exempt_log_ratio", gt=0.0,
                     who="moving_tracks")
    fast = moving_frames(tracks, speed_mps, probability, ego=ego,
                         doppler_std_mps=doppler_std_mps,
                         doppler_log_ratio_min=doppler_log_ratio_min, doppler_llr=doppler_llr,
                         doppler_log_ratio_floor=doppler_log_ratio_floor,
                         doppler_spread_std_mps=doppler_spread_std_mps,
                         doppler_reference=doppler_reference,
                         doppler_first_log_ratio=doppler_first_log_ratio,
                         crossing_prior=crossing_prior, crossing_log_ratio=crossing_log_ratio,
                         approach_probability=approach_probability,
                         approach_corridor_m=approach_corridor_m)
    order, key = _track_order(tracks)
    seen = pd.Series(fast[order]).groupby(key, sort=False).cummax().to_numpy(bool)
    out = np.empty(len(tracks), bool)
    out[order] = seen
    if points is not None and static_evidence_min > 0:
        clear = track_static_evidence(tracks, points, cell_m=static_cell_m,
                                      lag_frames=static_lag_frames) < static_evidence_min
        if static_exempt_log_ratio is not None:
            clear |= doppler_motion_evidence(tracks, doppler_std_mps, DOPPLER_FIRST_WINDOW
                                             ) >= static_exempt_log_ratio
        out &= clear
    return out


def moving_frames(tracks: pd.DataFrame, speed_mps: float, probability: float = 0.99, *,
                  ego: pd.DataFrame | None = None, doppler_std_mps: float = 0.3,
                  doppler_log_ratio_min: float | None = None,
                  doppler_llr: str = "common_variance",
                  doppler_log_ratio_floor: float | None = None,
                  doppler_spread_std_mps: tuple[float, float] | None = None,
                  doppler_reference: str = "frame",
                  doppler_first_log_ratio: float | None = None,
                  crossing_prior: CrossingPrior | None = None,
                  crossing_log_ratio: float | None = None,
                  approach_probability: float | None = None,
                  approach_corridor_m: float = 5.0) -> np.ndarray:
    """(N,) bool per row of ``tracks``: the row's own frame passes :func:`moving_tracks`'s
    kinematic and Doppler tests (confirmed, fast, significantly non-zero, the Doppler sum so
    far above its bound), before the latch and the static-evidence grid; same arguments and
    errors as :func:`moving_tracks`.

    With ``doppler_first_log_ratio`` (the Doppler-first path, issue 40) a confirmed, fast row
    whose track's own radial speeds over its last :data:`DOPPLER_FIRST_WINDOW` measured rows
    make "moving" at least that many natural-log units likelier than "static"
    (:func:`doppler_motion_evidence`, point spread ``doppler_std_mps``) passes without the
    kinematic chi-square test: the radar measures the radial speed in every frame, so a child
    stepping out with a radial component is seen moving from its first frames, while the
    filtered velocity needs several frames to become significant.

    With ``crossing_log_ratio`` and ``crossing_prior`` (the crossing prior, issue 40;
    :mod:`blindspot.track.crossing`) a confirmed row whose track's first radial speeds make "a
    pedestrian stepping toward the ego's path" at least that many natural-log units likelier
    than "static" (:func:`~blindspot.track.crossing.crossing_evidence`) is moving too, without
    the speed, kinematic and Doppler-refutation tests: its velocity across the road is not
    known yet, its radial speed's sign and scale are. That needs ``ego`` with ``ego_yaw_deg``
    (the path's direction). Raises ValueError when only one of the two is given.

    With ``approach_probability`` (the approach test, issue 40) a row's velocity is also
    significant when its component toward the ego's path passes the one-sided test
    :func:`~blindspot.track.crossing.approach_z` > Phi^-1(``approach_probability``) (rows within
    ``approach_corridor_m`` m of the path's line and ahead of the radar); the speed, confirmation
    and Doppler-refutation tests still apply. That needs ``ego`` with ``ego_yaw_deg`` too."""
    check_number(speed_mps, "speed_mps", ge=0.0, unit="m/s", who="moving_tracks")
    check_number(probability, "probability", gt=0.0, who="moving_tracks")
    if not probability < 1:
        raise ValueError(f"moving_tracks: probability: expected a number in (0, 1), found "
                         f"{probability!r}")
    check_number(doppler_std_mps, "doppler_std_mps", gt=0.0, unit="m/s", who="moving_tracks")
    need = {"group", "track_id", "frame", "vx_mps", "vy_mps", "cov_vxvx", "cov_vxvy",
            "cov_vyvy", "confirmed"}
    use_doppler = ego is not None and doppler_log_ratio_min is not None
    if use_doppler:
        need |= {"x_m", "y_m", "n_points", "doppler_mps"}
        if doppler_spread_std_mps is not None:
            need.add("doppler_spread_mps")
    check_columns(tracks, need, "tracks", note="the blindspot.track schema")
    if doppler_llr not in DOPPLER_LLR_FORMS:
        raise ValueError(f"doppler_llr: expected one of {list(DOPPLER_LLR_FORMS)}, found "
                         f"{doppler_llr!r}")
    if doppler_reference not in DOPPLER_REFERENCES:
        raise ValueError(f"doppler_reference: expected one of {list(DOPPLER_REFERENCES)}, "
                         f"found {doppler_reference!r}")
    if doppler_log_ratio_floor is not None and doppler_log_ratio_min is not None and not (
            doppler_log_ratio_floor <= doppler_log_ratio_min):
        raise ValueError(f"doppler_log_ratio_floor: expected at most doppler_log_ratio_min = "
                         f"{doppler_log_ratio_min}, found {doppler_log_ratio_floor!r}")
    speed = np.hypot(tracks.vx_mps.to_numpy(float), tracks.vy_mps.to_numpy(float))
    significant = velocity_chi2(tracks) > chi2.ppf(probability, 2)
    if approach_probability is not None:
        check_number(approach_probability, "approach_probability", gt=0.0, who="moving_tracks")
        if not approach_probability < 1:
            raise ValueError(f"moving_tracks: approach_probability: expected a number in (0, "
                             f"1), found {approach_probability!r}")
        if ego is None:
            raise ValueError("ego: expected the ego's poses (group, frame, ego_x_m, ego_y_m, "
                             "ego_yaw_deg) for the approach test, found None")
        check_number(approach_corridor_m, "approach_corridor_m", gt=0.0, unit="m",
                     who="moving_tracks")
        significant |= (approach_z(tracks, ego, approach_corridor_m)
                        > norm.ppf(approach_probability))
    if doppler_first_log_ratio is not None:
        significant |= doppler_motion_evidence(tracks, doppler_std_mps,
                                               DOPPLER_FIRST_WINDOW) >= doppler_first_log_ratio
    fast = (speed > speed_mps) & significant
    fast &= tracks.confirmed.to_numpy(bool)
    if use_doppler:
        fast &= doppler_evidence(tracks, ego, doppler_std_mps, doppler_llr,
                                 doppler_log_ratio_floor, spread_std_mps=doppler_spread_std_mps,
                                 reference=doppler_reference) > doppler_log_ratio_min
    if (crossing_prior is None) != (crossing_log_ratio is None):
        raise ValueError("crossing_prior, crossing_log_ratio: expected both or neither, found "
                         f"{type(crossing_prior).__name__} and {crossing_log_ratio!r}")
    if crossing_prior is not None:
        # > 0: rows outside the corridor, behind the radar or before a measurement score 0
        check_number(crossing_log_ratio, "crossing_log_ratio", gt=0.0, who="moving_tracks")
        if ego is None:
            raise ValueError("ego: expected the ego's poses (group, frame, ego_x_m, ego_y_m, "
                             "ego_yaw_deg) for the crossing test, found None")
        llr, _, _ = crossing_evidence(tracks, ego, crossing_prior)
        fast |= tracks.confirmed.to_numpy(bool) & (llr >= crossing_log_ratio)
    return fast


def velocity_chi2(tracks: pd.DataFrame) -> np.ndarray:
    """(N,) per row of ``tracks`` (columns vx_mps, vy_mps, cov_vxvx, cov_vxvy, cov_vyvy): the
    filtered velocity's squared Mahalanobis distance from zero, v^T P_v^-1 v (chi-square of 2
    degrees of freedom for a static object; :func:`moving_tracks`' kinematic test). NaN or inf
    where P_v is singular."""
    vx, vy = tracks.vx_mps.to_numpy(float), tracks.vy_mps.to_numpy(float)
    a, b, c = (tracks[k].to_numpy(float) for k in ("cov_vxvx", "cov_vxvy", "cov_vyvy"))
    with np.errstate(divide="ignore", invalid="ignore"):
        return (c * vx**2 - 2 * b * vx * vy + a * vy**2) / (a * c - b**2)


def doppler_evidence(tracks: pd.DataFrame, ego: pd.DataFrame, doppler_std_mps: float,
                     form: str = "common_variance", floor: float | None = None, *,
                     spread_std_mps: tuple[float, float] | None = None,
                     reference: str = "frame") -> np.ndarray:
    """(N,) per row of ``tracks``: the sum of :func:`doppler_log_ratio` (of ``form``) over the
    row's track up to and including its frame, "moves as tracked" against "static" in natural
    log units; with ``spread_std_mps`` = (static, walker) standard deviations (m/s) each
    frame's :func:`doppler_spread_log_ratio` is added. That sum is an approximation, not one
    likelihood: for Gaussian points the sample mean and the spread about it are independent,
    but the mean's ratio here uses the median and one point spread ``doppler_std_mps`` under
    both hypotheses, "walker" is not "moves as tracked" (a rigid moving object would be
    penalised), and frames whose spread comes from a fixed geometry are not independent. With
    ``floor`` the sum is reflected at it, S_t = max(floor, S_t-1 + llr_t) from S_0 = 0
    (Page 1954).

    ``reference`` "frame" (the above): each frame's ratio is taken at that frame's filtered
    velocity, so evidence gathered against an earlier velocity stays in the sum after the
    filter has corrected it (a clutter track that captures a child keeps the clutter's
    refutation, up to the floor). "current": every Doppler of the track so far is judged
    against the velocity it has now, S_t = sum_k<=t llr_k(v_t) (:func:`doppler_log_ratio_terms`,
    the quadratic's coefficients summed per track: vectorised): each frame's ratio re-evaluated
    at v_t with that frame's own variances (s1^2 holds the frame's velocity covariance, and the
    marginal form pays its Occam term every frame), so not the exact likelihood ratio of "it
    has moved at v_t all along". Without forgetting, a pedestrian who stood (Doppler 0) and
    then walks with a radial component is refuted by the standing frames: the reason it is not
    the default (README). The spread ratio (which does not depend on v) is summed as in
    "frame"; Page's floor does not apply (the sum is not a running recursion) and is ignored.

    ``ego``: columns group, frame, ego_x_m, ego_y_m (the radar's world position, m). Any row
    order. Raises ValueError naming a row without an ego position, a bad ``form``,
    ``reference`` or bad spreads."""
    e = tracks[["group", "frame"]].merge(ego[["group", "frame", "ego_x_m", "ego_y_m"]],
                                         on=["group", "frame"], how="left")
    if e.ego_x_m.isna().any():
        bad = e[e.ego_x_m.isna()].iloc[0]
        raise ValueError(f"ego: no radar position for group {bad.group!r} frame {bad.frame}")
    if reference not in DOPPLER_REFERENCES:
        raise ValueError(f"reference: expected one of {list(DOPPLER_REFERENCES)}, found "
                         f"{reference!r}")
    ego_xy = e[["ego_x_m", "ego_y_m"]].to_numpy(float)
    spread = (doppler_spread_log_ratio(tracks, *spread_std_mps) if spread_std_mps is not None
              else 0.0)
    order, key = _track_order(tracks)
    if reference == "current":
        c, a, b = doppler_log_ratio_terms(tracks, ego_xy, doppler_std_mps, form)
        coef = np.column_stack([c + spread, a, b[:, 0, 0], b[:, 0, 1], b[:, 1, 1]])
        cum = pd.DataFrame(coef[order]).groupby(key, sort=False).cumsum().to_numpy()
        vx = tracks.vx_mps.to_numpy(float)[order]
        vy = tracks.vy_mps.to_numpy(float)[order]
        total = (cum[:, 0] + cum[:, 1] * vx + cum[:, 2] * vy
                 - 0.5 * (cum[:, 3] * vx ** 2 + 2 * cum[:, 4] * vx * vy + cum[:, 5] * vy ** 2))
        out = np.empty(len(tracks))
        out[order] = total
        return out
    llr = doppler_log_ratio(tracks, ego_xy, doppler_std_mps, form) + spread
    total = pd.Series(llr[order]).groupby(key, sort=False).cumsum().to_numpy()
    if floor is not None:
        # Lindley's recursion in closed form: S_t = C_t - min(0, min_k<=t (C_k - floor))
        low = pd.Series(total - floor).groupby(key, sort=False).cummin()
        total = total - np.minimum(0.0, low.to_numpy())
    out = np.empty(len(tracks))
    out[order] = total
    return out


def _track_order(tracks: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """The row order that sorts ``tracks`` by group, track_id, frame, and each sorted row's
    track key."""
    order = np.lexsort((tracks.frame.to_numpy(), tracks.track_id.to_numpy(),
                        tracks.group.astype(str).to_numpy()))
    key = (tracks.group.astype(str) + "\x00" + tracks.track_id.astype(str)).to_numpy()[order]
    return order, key


def last_hit_rows(tracks: pd.DataFrame) -> np.ndarray:
    """(N,) int per row of ``tracks`` (columns group, track_id, frame, n_points): the position
    in ``tracks`` of the row itself where it has a measurement (n_points > 0), else of the
    track's last earlier row that had one (a coasting row's state is the filter's
    extrapolation, not something the radar saw); a row with no measured row before it in its
    track points to itself. Any row order. Raises ValueError naming a missing column."""
    check_columns(tracks, {"group", "track_id", "frame", "n_points"}, "tracks",
                  note="the blindspot.track schema")
    order, key = _track_order(tracks)
    hit = tracks.n_points.to_numpy(float)[order] > 0
    held = (pd.Series(np.where(hit, order, -1)).where(hit).groupby(key, sort=False).ffill()
            .to_numpy())
    out = np.empty(len(order), np.int64)
    out[order] = np.where(np.isnan(held), order, held).astype(np.int64)
    return out


def coast_frames(tracks: pd.DataFrame) -> np.ndarray:
    """(N,) int per row of ``tracks`` (columns group, track_id, frame, coasting): the frames
    since the row's track last had a measurement (0 on a measured row, ``coasting`` False; rows
    before a track's first measured row count from the track's first row). Any row order.
    Raises ValueError naming a missing column."""
    check_columns(tracks, {"group", "track_id", "frame", "coasting"}, "tracks",
                  note="the blindspot.track schema")
    order, key = _track_order(tracks)
    frame = tracks.frame.to_numpy(np.int64)[order]
    measured = ~tracks.coasting.to_numpy(bool)[order]
    last = pd.Series(np.where(measured, frame, np.nan)).groupby(key, sort=False).ffill()
    first = pd.Series(frame).groupby(key, sort=False).transform("first")
    out = np.empty(len(order), np.int64)
    out[order] = frame - last.fillna(first).to_numpy(np.int64)
    return out


def confirmed_moving(tracks: pd.DataFrame) -> np.ndarray:
    """(N,) bool per row of ``tracks``: confirmed and, where the table has a ``moving`` column
    (:func:`moving_tracks`), classed moving: the rows that stand for a moving object (the
    decision's, :func:`blindspot.safety.predict.decision_rows`, and the first-moving time's,
    :func:`blindspot.safety.evaluation.first_track_s`). Raises ValueError naming a missing
    ``confirmed`` column."""
    check_columns(tracks, {"confirmed"}, "tracks", note="the blindspot.track schema")
    keep = tracks.confirmed.to_numpy(bool).copy()
    if "moving" in tracks.columns:
        keep &= tracks.moving.to_numpy(bool)
    return keep


def track_static_evidence(tracks: pd.DataFrame, points: pd.DataFrame, *, cell_m: float,
                          lag_frames: int) -> np.ndarray:
    """(N,) int per row of ``tracks`` (columns group, track_id, frame, x_m, y_m, n_points): the
    :func:`static_evidence` count of the row's track at its last measured row
    (:func:`last_hit_rows`): a measured row's own count; a coasting row the count its track had
    at its last hit, at that hit's position and frame. The count is frozen there on purpose:
    the coasting row's position is the filter's extrapolation, and static hits that appear later
    at the last hit's position say nothing about where the object went. Same errors as the two.
    """
    return static_evidence(tracks, points, cell_m=cell_m,
                           lag_frames=lag_frames)[last_hit_rows(tracks)]


def moving_test_settings(m, grid: bool = True) -> dict[str, Any]:
    """The keyword arguments of :func:`moving_tracks` (``grid`` False: of
    :func:`moving_frames`, without the static-evidence grid's) that the tracker's moving-object
    settings ``m`` (:class:`blindspot.track.config.MovingConfig`, the group ``tracker.moving``)
    configure."""
    out = dict(speed_mps=m.speed_mps, probability=m.probability,
               doppler_std_mps=m.doppler_std_mps,
               doppler_log_ratio_min=m.doppler_log_ratio_min,
               doppler_llr=m.doppler_llr,
               doppler_log_ratio_floor=m.doppler_log_ratio_floor,
               doppler_spread_std_mps=m.doppler_spread_std_mps,
               doppler_reference=m.doppler_reference,
               doppler_first_log_ratio=m.doppler_first_log_ratio,
               crossing_prior=None if m.crossing_log_ratio is None else CrossingPrior(
                   speed_mps=m.crossing_speed_mps, speed_std_mps=m.crossing_speed_std_mps,
                   walker_std_mps=m.crossing_walker_std_mps,
                   static_std_mps=m.crossing_static_std_mps, window=m.crossing_window,
                   corridor_m=m.crossing_corridor_m),
               crossing_log_ratio=m.crossing_log_ratio,
               approach_probability=m.approach_probability,
               approach_corridor_m=m.crossing_corridor_m)
    if grid:
        out.update(static_evidence_min=m.static_evidence_min,
                   static_cell_m=m.static_cell_m,
                   static_lag_frames=m.static_lag_frames,
                   static_exempt_log_ratio=m.static_exempt_log_ratio)
    return out


def static_evidence(tracks: pd.DataFrame, points: pd.DataFrame, *, cell_m: float,
                    lag_frames: int) -> np.ndarray:
    """(N,) int per row of ``tracks`` (columns group, frame, x_m, y_m; world frame, m): the
    number of static radar points of the same group seen ``lag_frames`` or more frames before
    the row's frame within the 3 x 3 cells of side ``cell_m`` around the row's position (a
    point closer than ``cell_m`` in both axes always counts, one ``2 cell_m`` or farther in
    either axis never does).

    A static-environment evidence grid accumulated in the world frame (Werber et al. 2015,
    "Automotive radar gridmap representations", IEEE MTT-S ICMIM; the count is the
    occupancy evidence of a hit-count map): ``points`` (columns scene, frame, x_m, y_m, static:
    the ego-motion Doppler test of blindspot.dsp.driving, not a truth label) are the detections
    of every frame (non-finite ones dropped). Causal: frame f only sees points of frames
    <= f - ``lag_frames`` (``lag_frames`` >= 1), and the cells are a fixed world grid (their
    boundaries at multiples of ``cell_m``), so neither a later point nor another scene changes
    a row's count. A cluster sliding along a parked car's face stays on the car's past
    static hits; a child walking into the lane leaves them. Vectorised: one sort of the static
    points by (group, cell, frame), two binary searches per row and neighbour cell. Raises
    ValueError naming a missing column or a bad ``cell_m`` / ``lag_frames``."""
    for name, df, need in (("tracks", tracks, {"group", "frame", "x_m", "y_m"}),
                           ("points", points, {"scene", "frame", "x_m", "y_m", "static"})):
        check_columns(df, need, name)
    if not (np.isfinite(cell_m) and cell_m > 0):
        raise ValueError(f"cell_m: expected a positive cell size in m, found {cell_m!r}")
    if int(lag_frames) != lag_frames or lag_frames < 1:
        raise ValueError(f"lag_frames: expected an integer >= 1 (causal), found {lag_frames!r}")
    st = points[points.static.to_numpy(bool) & np.isfinite(points.x_m.to_numpy(float))
                & np.isfinite(points.y_m.to_numpy(float))]
    groups = pd.Index(pd.unique(np.r_[tracks.group.astype(str).to_numpy(),
                                      st.scene.astype(str).to_numpy()]))
    tx, ty = tracks.x_m.to_numpy(float), tracks.y_m.to_numpy(float)
    px, py = st.x_m.to_numpy(float), st.y_m.to_numpy(float)
    ok_t = np.isfinite(tx) & np.isfinite(ty)
    # cells of a fixed world grid (boundaries at multiples of cell_m), so no other point, later
    # frame or other scene can move them; the offsets only make the packed keys non-negative
    cx_p, cy_p = np.floor(px / cell_m), np.floor(py / cell_m)
    cx_t = np.floor(np.where(ok_t, tx, 0.0) / cell_m)
    cy_t = np.floor(np.where(ok_t, ty, 0.0) / cell_m)
    ox = np.min(np.r_[cx_p, cx_t, 0.0]) - 2
    oy = np.min(np.r_[cy_p, cy_t, 0.0]) - 2
    ix_p, iy_p = (cx_p - ox).astype(np.int64), (cy_p - oy).astype(np.int64)
    ix_t, iy_t = (cx_t - ox).astype(np.int64), (cy_t - oy).astype(np.int64)
    nx = int(max(ix_p.max(initial=0), ix_t.max(initial=0))) + 3
    ny = int(max(iy_p.max(initial=0), iy_t.max(initial=0))) + 3
    frame_p = st.frame.to_numpy(np.int64)
    frame_t = tracks.frame.to_numpy(np.int64)
    nf = int(max(frame_p.max(initial=0), frame_t.max(initial=0))) + 2
    g_p = groups.get_indexer(st.scene.astype(str)).astype(np.int64)
    g_t = groups.get_indexer(tracks.group.astype(str)).astype(np.int64)
    keys = np.sort(((g_p * nx + ix_p) * ny + iy_p) * nf + frame_p)
    upto = frame_t - int(lag_frames) + 1                   # frames < upto count
    count = np.zeros(len(tracks), np.int64)
    for dx in (-1, 0, 1):                                  # the 3 x 3 neighbourhood
        for dy in (-1, 0, 1):
            base = ((g_t * nx + ix_t + dx) * ny + iy_t + dy) * nf
            hi = np.searchsorted(keys, base + np.maximum(upto, 0), side="left")
            lo = np.searchsorted(keys, base, side="left")
            count += hi - lo
    return np.where(ok_t, count, 0)
