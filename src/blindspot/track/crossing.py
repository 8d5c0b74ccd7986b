"""The crossing prior: is a young track a pedestrian stepping toward the ego's lane, or static?

A child stepping out from behind a parked car moves across the road, nearly tangentially to a
radar 10-25 m behind it: the ego-motion-compensated radial speed of its points is small (about
-1.4 m/s times the sine of its bearing off the road's axis, -0.1 to -0.3 m/s) but has a known
sign and scale, and its first frames carry no kinematic velocity yet. The context that the
scene gives (issue 40: "an object appearing at the edge of a parked car's shadow, moving
toward the lane") is put into the prior of one hypothesis:

* H1, a crosser: the object moves toward the line of the ego's path (perpendicular to the ego's
  heading, from the object's side) at a speed s ~ N(``speed_mps``, ``speed_std_mps``^2); each
  frame's median radial speed d_k of n_k points is d_k = s b_k + e_k, b_k = u_k . c_k (u the
  unit line of sight from the radar, c the unit vector toward the path), e_k ~ N(0,
  ``walker_std_mps``^2 / n_k) (the walker's micro-Doppler spread about its body);
* H0, static: d_k ~ N(0, ``static_std_mps``^2 / n_k) (the static world's residual spread).

With s marginalised, the frames' radial speeds are jointly Gaussian under H1 with covariance
D1 + tau^2 b b^T (tau = ``speed_std_mps``); the Sherman-Morrison identity gives the log
likelihood ratio in closed form from per-track running sums over the track's first ``window``
measured rows (Kay 1998, "Fundamentals of Statistical Signal Processing II", sec. 5.6: the
Bayesian linear model's detector). The same sums give the posterior of s under H1
(:func:`crossing_evidence`'s ``speed``), the velocity a crossing track's decision may use.
Objects further than ``corridor_m`` beside the ego's path, or behind the radar, get 0.

Once a track has a few frames of positions, its filtered velocity says the same thing with a
direction: :func:`approach_z` is the velocity's component toward the ego's path in standard
deviations of the filter's own covariance, c.v / sqrt(c^T P_v c). A static object's filtered
velocity is zero-mean Gaussian with covariance P_v, so a one-sided test z > Phi^-1(p) passes
it with probability 1 - p per frame: the test of the moving test's 2-dof chi-square (Bar-Shalom,
Li & Kirubarajan 2001, sec. 5.4) restricted to the one direction that matters here. A walker
crossing in cross-range (the direction the radar's angle measures worst) needs fewer frames
for it: at p = 0.9 it passes at 1.28 sigma along c, where the chi-square at p = 0.99 needs
3.03 sigma on the norm (issue 40: 97 % of the lead child's confirmed rows before it was classed
moving failed that chi-square; ``docs/studies/first-point-to-brake.md``, "Third pass").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from blindspot.arrays import check_number
from blindspot.tables import check_columns

__all__ = ["CrossingPrior", "approach_z", "crossing_evidence", "toward_path"]


@dataclass(frozen=True)
class CrossingPrior:
    """The crossing hypothesis' settings (``tracker.moving.crossing_*``; module docstring)."""

    speed_mps: float = 1.4          # m/s, a walking child's crossing speed (Euro NCAP: 5 km/h)
    speed_std_mps: float = 0.5      # m/s, its spread
    walker_std_mps: float = 0.35    # m/s, a walker's point radial-speed spread about its body
    static_std_mps: float = 0.15    # m/s, a static point's residual radial speed
    window: int = 3                 # measured rows from a track's birth that the test pools
    corridor_m: float = 5.0         # m, largest offset beside the ego's path that is tested

    def __post_init__(self) -> None:
        for name in ("speed_mps", "speed_std_mps", "walker_std_mps", "static_std_mps",
                     "corridor_m"):
            check_number(getattr(self, name), name, gt=0.0, who="CrossingPrior")
        if not (isinstance(self.window, (int, np.integer)) and self.window >= 1):
            raise ValueError(f"CrossingPrior: window: expected an integer >= 1, found "
                             f"{self.window!r}")


def toward_path(tracks: pd.DataFrame, ego: pd.DataFrame) -> tuple[np.ndarray, ...]:
    """Per row of ``tracks`` (group, frame, x_m, y_m) with the ego's pose of its frame
    (``ego``: group, frame, ego_x_m, ego_y_m, ego_yaw_deg; yaw 0 = +y, positive to the left):
    (c (N, 2) the unit vector from the row toward the line of the ego's path, perpendicular to
    its heading; lateral (N,) m, the row's offset beside that line; ahead (N,) m, its distance
    along the heading; u (N, 2) the unit line of sight from the radar). Raises ValueError
    naming a missing column or a row without an ego pose."""
    need = {"group", "frame", "ego_x_m", "ego_y_m", "ego_yaw_deg"}
    check_columns(ego, need, "ego", note="the ego's poses: group, frame, ego_x_m, ego_y_m, "
                                          "ego_yaw_deg")
    pose = tracks[["group", "frame"]].merge(ego[list(need)], on=["group", "frame"],
                                            how="left")
    if pose.ego_x_m.isna().any():
        bad = pose[pose.ego_x_m.isna()].iloc[0]
        raise ValueError(f"ego: no pose for group {bad.group!r} frame {bad.frame}")
    yaw = np.radians(pose.ego_yaw_deg.to_numpy(float))
    fwd = np.c_[-np.sin(yaw), np.cos(yaw)]
    left = np.c_[-np.cos(yaw), -np.sin(yaw)]
    rel = (tracks[["x_m", "y_m"]].to_numpy(float)
           - pose[["ego_x_m", "ego_y_m"]].to_numpy(float))
    lateral = (rel * left).sum(axis=1)
    ahead = (rel * fwd).sum(axis=1)
    c = -np.sign(lateral)[:, None] * left
    rng = np.hypot(rel[:, 0], rel[:, 1])
    u = rel / np.where(rng > 0, rng, 1.0)[:, None]
    return c, lateral, ahead, u


def approach_z(tracks: pd.DataFrame, ego: pd.DataFrame, corridor_m: float) -> np.ndarray:
    """(N,) per row of ``tracks`` (columns group, frame, x_m, y_m, vx_mps, vy_mps, cov_vxvx,
    cov_vxvy, cov_vyvy; the tracker's world-frame filtered state): the velocity's component
    toward the line of the ego's path in standard deviations of the row's velocity covariance
    (module docstring); 0 for rows further than ``corridor_m`` m beside that line, behind the
    radar, on the line itself or with a degenerate covariance. Raises ValueError naming a
    missing column, a row without an ego pose (:func:`toward_path`) or a ``corridor_m`` not > 0.
    """
    check_number(corridor_m, "corridor_m", gt=0.0, unit="m", who="approach_z")
    check_columns(tracks, {"group", "frame", "x_m", "y_m", "vx_mps", "vy_mps", "cov_vxvx",
                           "cov_vxvy", "cov_vyvy"}, "tracks", note="the blindspot.track schema")
    c, lateral, ahead, _ = toward_path(tracks, ego)
    v = tracks[["vx_mps", "vy_mps"]].to_numpy(float)
    pxx, pxy, pyy = (tracks[k].to_numpy(float) for k in ("cov_vxvx", "cov_vxvy", "cov_vyvy"))
    var = c[:, 0] ** 2 * pxx + 2 * c[:, 0] * c[:, 1] * pxy + c[:, 1] ** 2 * pyy
    ok = (np.abs(lateral) <= corridor_m) & (ahead > 0) & (var > 0) & np.isfinite(var)
    z = (v * c).sum(axis=1) / np.sqrt(np.where(ok, var, 1.0))
    return np.where(ok & np.isfinite(z), z, 0.0)


def crossing_evidence(tracks: pd.DataFrame, ego: pd.DataFrame,
                      prior: CrossingPrior) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of ``tracks`` (columns group, track_id, frame, x_m, y_m, n_points,
    doppler_mps; any order), over its track's first ``prior.window`` measured rows up to the
    row: (llr (N,) the log likelihood ratio crosser / static of the module docstring, 0 before
    any measured row, held at its window's value after the window (so a track that passed
    stays passed); speed (N,) m/s, the posterior mean of the crossing speed s under H1;
    speed_std (N,) m/s, its standard deviation). Rows outside the corridor or behind the radar
    add nothing. Raises ValueError naming a missing column (:func:`toward_path` for ``ego``)."""
    if not isinstance(prior, CrossingPrior):
        raise ValueError(f"prior: expected a CrossingPrior, found {type(prior).__name__}")
    check_columns(tracks, {"group", "track_id", "frame", "x_m", "y_m", "n_points",
                           "doppler_mps"}, "tracks", note="the blindspot.track schema")
    c, lateral, ahead, u = toward_path(tracks, ego)
    b = (u * c).sum(axis=1)
    n = tracks.n_points.to_numpy(float)
    d = tracks.doppler_mps.to_numpy(float)
    measured = (n > 0) & np.isfinite(d)
    ok = measured & (np.abs(lateral) <= prior.corridor_m) & (ahead > 0) & np.isfinite(b)
    key = pd.MultiIndex.from_frame(tracks[["group", "track_id"]]).codes
    key = key[0].astype(np.int64) * (int(key[1].max(initial=0)) + 1) + key[1]
    order = np.lexsort((tracks.frame.to_numpy(), key))
    ok_o, key_o = ok[order], key[order]
    # the window is the track's first measured rows from its birth; of those, the ones in the
    # corridor and ahead are pooled (an old track entering the corridor is not young)
    rank = pd.Series(measured[order].astype(int)).groupby(key_o, sort=False).cumsum().to_numpy()
    use = ok_o & (rank <= prior.window)
    w = np.where(use, n[order] / prior.walker_std_mps ** 2, 0.0)
    bo, do = np.where(use, b[order], 0.0), np.where(use, d[order], 0.0)
    terms = {"A": w * bo ** 2, "Bd": w * bo * do, "Q1": w * do ** 2,
             "Q0": np.where(use, n[order] * do ** 2 / prior.static_std_mps ** 2, 0.0),
             "K": use.astype(float)}
    s = pd.DataFrame(terms).groupby(key_o, sort=False).cumsum()
    a, bd, q1, q0, k = (s[c].to_numpy() for c in ("A", "Bd", "Q1", "Q0", "K"))
    mu, tau2 = prior.speed_mps, prior.speed_std_mps ** 2
    bb = bd - mu * a                                   # sum w b (d - mu b)
    q = q1 - 2 * mu * bd + mu * mu * a                 # sum w (d - mu b)^2
    l1 = -0.5 * (q - tau2 * bb ** 2 / (1 + tau2 * a) + np.log1p(tau2 * a)
                 + 2 * k * np.log(prior.walker_std_mps))
    l0 = -0.5 * (q0 + 2 * k * np.log(prior.static_std_mps))
    prec = 1.0 / tau2 + a
    out = [np.empty(len(tracks)) for _ in range(3)]
    for arr, val in zip(out, (l1 - l0, (mu / tau2 + bd) / prec, 1.0 / np.sqrt(prec))):
        arr[order] = val
    return out[0], out[1], out[2]


def crossing_state(tracks: pd.DataFrame, ego: pd.DataFrame, prior: CrossingPrior,
                   rows: np.ndarray, init_velocity_std_mps: float) -> pd.DataFrame:
    """A copy of ``tracks`` whose ``rows`` ((N,) bool: the rows a decision reads as crossers)
    carry the state under the crossing prior instead of the tracker's zero-mean one.

    Along the unit vector c toward the ego's path (:func:`toward_path`) the tracker's state was
    formed under a N(0, s0^2) velocity prior (s0 = ``init_velocity_std_mps``); the crossing
    prior is N(mu, tau^2) (``prior.speed_mps``, ``prior.speed_std_mps``, tau < s0). Swapping
    one Gaussian prior of c.v for another multiplies the posterior by N(mu, tau^2) / N(0, s0^2),
    which is the likelihood of a pseudo-measurement of c.v with precision
    1 / tau^2 - 1 / s0^2 and value z = (mu / tau^2) / (1 / tau^2 - 1 / s0^2). It is applied as
    one scalar Kalman update of the whole state [x, vx, y, vy] with h = [0, cx, 0, cy], so the
    covariance stays positive semi-definite and the components across c and the positions move
    with their correlations (exact for a linear-Gaussian filter without process noise; with it
    the old prior's weight has partly decayed, a slight over-correction in a young track).
    Rows on the path's line (no direction toward it) are left as they are. Raises ValueError
    for ``rows`` of another length, or a prior not narrower than ``init_velocity_std_mps``."""
    check_number(init_velocity_std_mps, "init_velocity_std_mps", gt=0.0, unit="m/s",
                 who="crossing_state")
    if not prior.speed_std_mps < init_velocity_std_mps:
        raise ValueError(f"crossing_state: prior.speed_std_mps: expected less than "
                         f"init_velocity_std_mps = {init_velocity_std_mps}, found "
                         f"{prior.speed_std_mps!r}")
    rows = np.asarray(rows, bool)
    if rows.shape != (len(tracks),):
        raise ValueError(f"rows: expected a bool array of length {len(tracks)}, found shape "
                         f"{rows.shape}")
    out = tracks.copy()
    if not rows.any():
        return out
    sel = tracks[rows]
    c, _, _, _ = toward_path(sel, ego)
    has = np.hypot(c[:, 0], c[:, 1]) > 0
    cols = ["x_m", "vx_mps", "y_m", "vy_mps"]
    x = sel[cols].to_numpy(float)
    cov = {("x", "x"): "cov_xx", ("x", "y"): "cov_xy", ("y", "y"): "cov_yy",
           ("vx", "vx"): "cov_vxvx", ("vx", "vy"): "cov_vxvy", ("vy", "vy"): "cov_vyvy",
           ("x", "vx"): "cov_xvx", ("x", "vy"): "cov_xvy", ("y", "vx"): "cov_yvx",
           ("y", "vy"): "cov_yvy"}
    names = ["x", "vx", "y", "vy"]
    P = np.zeros((len(sel), 4, 4))
    for i, a in enumerate(names):
        for j, b in enumerate(names):
            key = cov.get((a, b)) or cov.get((b, a))
            if key in sel.columns:
                P[:, i, j] = sel[key].to_numpy(float)
    h = np.zeros((len(sel), 4))
    h[:, 1], h[:, 3] = c[:, 0], c[:, 1]
    prec = 1.0 / prior.speed_std_mps ** 2 - 1.0 / init_velocity_std_mps ** 2
    z = (prior.speed_mps / prior.speed_std_mps ** 2) / prec
    ph = np.einsum("kij,kj->ki", P, h)
    k = ph / (np.einsum("ki,ki->k", h, ph) + 1.0 / prec)[:, None]
    x_new = x + k * (z - np.einsum("ki,ki->k", h, x))[:, None]
    P_new = P - k[:, :, None] * ph[:, None, :]
    P_new = 0.5 * (P_new + np.swapaxes(P_new, 1, 2))
    x_new = np.where(has[:, None], x_new, x)
    P_new = np.where(has[:, None, None], P_new, P)
    out.loc[rows, cols] = x_new
    for (a, b), key in cov.items():
        if key in out.columns:
            out.loc[rows, key] = P_new[:, names.index(a), names.index(b)]
    return out
