"""Scene outcomes of a committed AEB: the braked ego car against the pedestrians' TRUE paths.

Once the AEB request is issued at time t_req (decision time), the ego's front-bumper centre
moves along its heading (+y; the scenes' ego drives straight, yaw 0) as
``y(t) = y(0) + v0 min(t, t_req) + s(t - t_req)`` with ``s`` the :class:`BrakingModel` distance.
Each pedestrian's box (length along its heading, width across, reference point
``ref_from_front_m`` behind the front; the [V] boxes of the scenario group) follows its truth
path (``data/driving/truth.parquet``: reference point and velocity per 0.1 s frame), linearly
interpolated between frames and continued at its last velocity past the scene's end (for
``extend_s``), heading = the direction of its velocity (a pedestrian at rest keeps the heading
it walks off with). Contact = the ego rectangle (width W across, length L behind the bumper)
overlaps the box's axis-aligned bounding box (exact for boxes aligned with the road, as the
crossing paths are; a conservative envelope on the arcs of turning paths), on a grid of
``dt_s``. The first contact's time and the ego's speed then is the impact (Euro NCAP's relative
impact speed for a pedestrian crossing the ego's path); no contact = avoided.

Everything is vectorised over scenes (in chunks), trigger times, pedestrians and the time grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from blindspot.arrays import check_number
from blindspot.safety.braking import BrakingModel
from blindspot.safety.risk import EgoShape
from blindspot.tables import check_columns

__all__ = ["OutcomeError", "SceneArrays", "body_boxes", "scene_arrays", "pedestrian_boxes",
           "braked_impacts", "NEVER_S"]

NEVER_S = 1e9          # the trigger time of "no AEB request"


class OutcomeError(ValueError):
    """Malformed truth tables or arguments."""


@dataclass(frozen=True)
class SceneArrays:
    """Truth of S scenes on one frame grid.

    scenes (S,) names; time_s (F,) s; ego_x_m, ego_y0_m (S,) front-bumper centre at frame 0,
    speed_mps (S,); pos, vel (S, P, F, 2) m, m/s (NaN where a scene has fewer pedestrians);
    present (S, P) bool; length_m, width_m, ref_front_m (S, P) the pedestrian boxes."""

    scenes: np.ndarray
    time_s: np.ndarray
    ego_x_m: np.ndarray
    ego_y0_m: np.ndarray
    speed_mps: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    present: np.ndarray
    length_m: np.ndarray
    width_m: np.ndarray
    ref_front_m: np.ndarray


def body_boxes(group) -> dict[str, tuple[float, float, float]]:
    """The ``bodies`` argument of :func:`scene_arrays` from a scenario group
    (:class:`blindspot.radar.scenario.ScenarioGroup`): body name -> (length_m, width_m,
    ref_from_front_m), the [V] boxes of ``conf/scenario``."""
    return {b.name: (b.length_m, b.width_m, b.ref_from_front_m) for b in group.bodies}


def scene_arrays(truth: pd.DataFrame, bodies: dict[str, tuple[float, float, float]],
                 where: str = "truth") -> SceneArrays:
    """Arrays of a truth table (columns of :data:`blindspot.radar.driving.TRUTH_COLUMNS`).

    bodies: body name -> (length_m, width_m, ref_from_front_m). Raises OutcomeError naming
    ``where`` for missing columns, scenes on different frame grids, a turning ego (yaw != 0) or
    a body not in ``bodies``.
    """
    check_columns(truth, {"scene", "frame", "time_s", "ego_x_m", "ego_y_m", "ego_yaw_deg",
                          "ego_speed_mps", "pedestrian", "body", "x_m", "y_m", "vx_mps",
                          "vy_mps"}, where, error=OutcomeError)
    if not np.allclose(truth.ego_yaw_deg.to_numpy(), 0.0):
        raise OutcomeError(f"{where}: the outcome model needs an ego driving straight along +y "
                           "(ego_yaw_deg 0), found other headings")
    unknown = sorted(set(truth.body) - set(bodies))
    if unknown:
        raise OutcomeError(f"{where}: bodies {unknown} not in the scenario group "
                           f"({sorted(bodies)})")
    t = truth.sort_values(["scene", "pedestrian", "frame"])
    scenes = np.array(sorted(t.scene.unique()))
    frames = np.sort(t.frame.unique())
    times = t.groupby("frame").time_s.first().reindex(frames).to_numpy()
    per_scene = t.groupby("scene").frame.nunique()
    if (per_scene != len(frames)).any():
        raise OutcomeError(f"{where}: every scene must cover frames {frames[0]}..{frames[-1]}; "
                           f"{int((per_scene != len(frames)).sum())} scenes do not")
    si = np.searchsorted(scenes, t.scene.to_numpy())
    peds = t.groupby("scene").pedestrian.transform(lambda s: pd.factorize(s, sort=True)[0])
    pi = peds.to_numpy()
    fi = np.searchsorted(frames, t.frame.to_numpy())
    S, P, F = len(scenes), int(pi.max()) + 1, len(frames)
    pos = np.full((S, P, F, 2), np.nan)
    vel = np.full((S, P, F, 2), np.nan)
    pos[si, pi, fi] = t[["x_m", "y_m"]].to_numpy()
    vel[si, pi, fi] = t[["vx_mps", "vy_mps"]].to_numpy()
    present = np.zeros((S, P), bool)
    present[si, pi] = True
    dims = np.full((S, P, 3), np.nan)
    dims[si, pi] = np.array([bodies[b] for b in t.body])
    first = t.frame.to_numpy() == frames[0]
    ego_x = np.zeros(S)
    ego_y = np.zeros(S)
    speed = np.zeros(S)
    ego_x[si[first]] = t.ego_x_m.to_numpy()[first]
    ego_y[si[first]] = t.ego_y_m.to_numpy()[first]
    speed[si[first]] = t.ego_speed_mps.to_numpy()[first]
    return SceneArrays(scenes, times, ego_x, ego_y, speed, pos, vel, present,
                       dims[..., 0], dims[..., 1], dims[..., 2])


def _fill_heading(vel: np.ndarray) -> np.ndarray:
    """(..., F, 2) velocities -> unit headings; frames at rest take the next moving frame's
    heading (then the previous one's; +y if it never moves)."""
    speed = np.linalg.norm(vel, axis=-1)
    moving = np.nan_to_num(speed) > 1e-6
    unit = np.where(moving[..., None], vel / np.where(moving, speed, 1.0)[..., None], np.nan)
    F = vel.shape[-2]
    idx = np.arange(F)
    nxt = np.where(moving, idx, F)
    nxt = np.minimum.accumulate(nxt[..., ::-1], axis=-1)[..., ::-1]       # next moving frame
    prv = np.maximum.accumulate(np.where(moving, idx, -1), axis=-1)       # previous one
    pick = np.where(nxt < F, nxt, np.maximum(prv, 0))
    h = np.take_along_axis(unit, pick[..., None], axis=-2)
    return np.where(np.isfinite(h), h, np.array([0.0, 1.0]))


def pedestrian_boxes(sa: SceneArrays, dt_s: float, extend_s: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time grid t (T,) s and the boxes' axis-aligned bounds lo, hi (S, P, T, 2) m (NaN for
    absent pedestrians); see the module docstring."""
    dt_s = check_number(dt_s, "dt_s", gt=0.0, unit="s", error=OutcomeError,
                        who="pedestrian_boxes")
    extend_s = check_number(extend_s, "extend_s", ge=0.0, unit="s", error=OutcomeError,
                            who="pedestrian_boxes")
    tf = sa.time_s
    t = np.arange(tf[0], tf[-1] + extend_s + dt_s / 2, dt_s)
    k = np.clip(np.searchsorted(tf, t, side="right") - 1, 0, len(tf) - 1)
    k1 = np.minimum(k + 1, len(tf) - 1)
    span = np.where(k1 > k, tf[k1] - tf[k], 1.0)
    frac = np.where(k1 > k, (t - tf[k]) / span, 0.0)
    past = np.maximum(t - tf[-1], 0.0)
    p0, p1 = sa.pos[:, :, k], sa.pos[:, :, k1]                           # (S, P, T, 2)
    ref = p0 + frac[:, None] * (p1 - p0) + past[:, None] * sa.vel[:, :, -1:, :]
    head = _fill_heading(sa.vel)[:, :, k]                                 # (S, P, T, 2)
    L = sa.length_m[..., None]
    W = sa.width_m[..., None]
    # box centre, and its bounding half-extents: |h_x| L/2 + |h_y| W/2 across x, and so on
    centre = ref + (sa.ref_front_m[..., None] - L / 2)[..., None] * head
    ah = np.abs(head)
    half = np.stack([ah[..., 0] * L / 2 + ah[..., 1] * W / 2,
                     ah[..., 1] * L / 2 + ah[..., 0] * W / 2], -1)
    return t, centre - half, centre + half


def braked_impacts(sa: SceneArrays, t: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                   trigger_s: np.ndarray, braking: BrakingModel, ego: EgoShape, *,
                   chunk: int = 16, with_front: bool = False) -> tuple[np.ndarray, ...]:
    """First contact of the braked ego with any pedestrian of each scene.

    t (T,), lo / hi (S, P, T, 2) from :func:`pedestrian_boxes`; trigger_s (S, K) AEB request
    times, s (:data:`NEVER_S` = never). Returns impact_time_s and impact_speed_mps (S, K), NaN
    where the collision is avoided; with ``with_front`` also front (S, K) bool: the first
    contact is a front contact, the pedestrian's box reaching the bumper line (its far edge
    along the travel at or ahead of the bumper, less one grid step of the ego's travel), not a
    pedestrian walking into the car's flank behind the bumper (Euro NCAP scores front impacts;
    issue 40 counts flank contacts apart). Vectorised in chunks of ``chunk`` scenes (memory).
    """
    trig = np.asarray(trigger_s, float)
    S = len(sa.scenes)
    if trig.ndim != 2 or trig.shape[0] != S:
        raise OutcomeError(f"braked_impacts: trigger_s must be (S={S}, K), found {trig.shape}")
    out_t = np.full(trig.shape, np.nan)
    out_v = np.full(trig.shape, np.nan)
    out_front = np.zeros(trig.shape, bool)
    step = float(t[1] - t[0]) if len(t) > 1 else 0.0
    hw = ego.width_m / 2
    for a in range(0, S, chunk):                       # memory chunks (not a loop per scene)
        b = min(a + chunk, S)
        x0 = sa.ego_x_m[a:b, None, None]
        lat = (lo[a:b, ..., 0] <= x0 + hw) & (hi[a:b, ..., 0] >= x0 - hw)   # (s, P, T)
        lat &= sa.present[a:b, :, None]
        cols = np.flatnonzero(lat.any(axis=(0, 1)))   # only instants with a pedestrian in the
        if not len(cols):                             # ego's lateral span can be contacts
            continue
        lat = lat[..., cols]
        tt = t[None, None, cols]
        v0 = sa.speed_mps[a:b, None, None]
        tr = trig[a:b, :, None]                                            # (s, K, 1)
        s_b, v_b = braking.motion(v0, np.maximum(tt - tr, 0.0))
        braked = tt > tr
        yb = sa.ego_y0_m[a:b, None, None] + v0 * np.minimum(tt, tr) + np.where(braked, s_b, 0.0)
        speed = np.where(braked, v_b, v0)
        ylo, yhi = lo[a:b, None, :, cols, 1], hi[a:b, None, :, cols, 1]     # (s, 1, P, C)
        hit = (lat[:, None] & (ylo <= yb[:, :, None]) &
               (yhi >= yb[:, :, None] - ego.length_m)).any(axis=2)          # (s, K, C)
        anyhit = hit.any(-1)
        first = np.argmax(hit, -1)
        out_t[a:b] = np.where(anyhit, t[cols][first], np.nan)
        out_v[a:b] = np.where(anyhit, np.take_along_axis(speed, first[..., None], -1)[..., 0],
                              np.nan)
        if with_front:
            # at the first contact: does any touching box reach the bumper line?
            reach = yhi >= (yb - speed * step - 1e-9)[:, :, None]              # (s, K, P, C)
            front = (lat[:, None] & (ylo <= yb[:, :, None])
                     & (yhi >= yb[:, :, None] - ego.length_m) & reach).any(axis=2)
            out_front[a:b] = anyhit & np.take_along_axis(front, first[..., None], -1)[..., 0]
    return (out_t, out_v, out_front) if with_front else (out_t, out_v)
