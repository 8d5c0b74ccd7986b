"""The detection chain on a moving car: range-Doppler, CFAR, Doppler unwrapping with the ego
speed, TDM-MIMO compensation with the unwrapped velocity, angles, ego-motion, static clutter
removal on the ego-motion Doppler curve, points in the vehicle frame.

Per batch of frames (every step vectorised over the batch's detections):

1. Range and Doppler FFTs, detection map, CFAR and local maxima: the steps of
   :class:`blindspot.dsp.chain.DetectionChain` (same configuration groups).
2. The ``max_detections`` strongest peaks of each frame get angles (the static world gives most
   of them: the ego-motion fit needs them).
3. Ambiguity order: the Doppler bin gives v modulo 2 v_max. For each candidate order m (those
   that can reach the static world's ``-v_odo cos(theta)`` for some azimuth, +-v_max),
   the snapshots are TDM-compensated with ``v_m = v_wrapped + 2 m v_max``
   (:func:`~blindspot.dsp.doppler_compensation.compensate_tdm_velocity`) and the angle
   ``theta_m`` estimated; the order kept is the one whose velocity is nearest the static world's
   at its own angle, ``|v_m + v_odo cos(theta_m)|`` smallest: the order
   :func:`~blindspot.dsp.ego_motion.unwrap_doppler` chooses at the angle estimated under it.
   A wrong order compensates with a phase error ``2 pi m t_k / T_loop`` that shifts and smears
   the angle; the velocity it implies is ``2 m v_max`` away from the curve, so it loses.
4. Ego speed from the radar: :func:`~blindspot.dsp.ego_motion.estimate_ego_speed` (RANSAC,
   Kellner et al. 2013) per frame; detections within ``static_tolerance_mps`` of
   ``-v_radar cos(theta)`` are static (clutter on a moving car), the others moving.
5. Points ``x = R sin(theta)``, ``y = R cos(theta)`` in the vehicle frame (radar at the bumper,
   boresight +y); the world frame needs the ego pose (:func:`blindspot.radar.driving.vehicle_to_world`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.doa import doa_angles
from blindspot.dsp.doppler_compensation import compensate_tdm_velocity
from blindspot.dsp.ego_motion import EgoMotionConfig, estimate_ego_speed, static_radial_velocity
from blindspot.dsp.snapshots import cell_snapshots
from blindspot.radar.array import VirtualArray
from blindspot.radar.config import RadarConfig

DRIVING_DETECTION_COLUMNS = (
    "frame", "range_bin", "doppler_bin", "range_m", "velocity_wrapped_mps", "ambiguity_order",
    "velocity_mps", "angle_deg", "power", "snr_db", "static", "x_vehicle_m", "y_vehicle_m",
)
EGO_COLUMNS = ("frame", "odometry_mps", "ego_speed_mps", "n_detections", "n_static")


@dataclass
class DrivingBatch:
    """Detections (``DRIVING_DETECTION_COLUMNS``) and per-frame ego speeds (``EGO_COLUMNS``) of a
    batch; the maps (F, range, doppler) when asked for."""

    detections: pd.DataFrame
    ego: pd.DataFrame
    power: np.ndarray | None = None
    threshold: np.ndarray | None = None


class DrivingChain:
    """The moving-car chain for one radar profile (e.g. ``conf/radar/mmwcas_driving.yaml``)."""

    def __init__(self, radar: RadarConfig, array: VirtualArray, cfar, doa, detect,
                 ego: EgoMotionConfig):
        base = DetectionChain.from_config(radar, array, cfar, doa, detect)
        # the driving chain's own range window and angle budget (static detections are wanted)
        self.base = DetectionChain(radar, array, base.cfar, base.doa,
                                   replace(base.detect, max_range_m=ego.max_range_m,
                                           max_detections=ego.max_detections))
        self.radar, self.ego = radar, ego
        self.v_max = radar.max_velocity_mps

    def candidate_orders(self, odometry_mps: float) -> np.ndarray:
        """Orders m that can bring a wrapped velocity within +-v_max of the static world's value
        ``-v cos(theta)``, theta in +-90 deg (values in [-v - v_max, v_max])."""
        lo = int(np.floor((-abs(odometry_mps) - 2 * self.v_max) / (2 * self.v_max)))
        hi = int(np.ceil(2 * self.v_max / (2 * self.v_max)))
        return np.arange(lo, hi + 1)

    def process_batch(self, cubes: np.ndarray, odometry_mps: np.ndarray, frames: np.ndarray,
                      *, keep_maps: bool = False) -> DrivingBatch:
        """cubes (F, chirps, tx, rx, samples), odometry speed (F,) m/s, frame numbers (F,)."""
        ch = self.base
        odo = np.asarray(odometry_mps, dtype=float)
        frames = np.asarray(frames, dtype=np.int64)
        rd, _ = ch.range_doppler(cubes)
        power = ch.detection_map(rd)
        mask, threshold, noise = ch.run_cfar(power)
        fi, rb, db = ch.select_cells(power, mask)
        pw = power[fi, rb, db]
        order = np.lexsort((-pw, fi))                        # per frame strongest first
        fi, rb, db, pw = fi[order], rb[order], db[order], pw[order]
        keep = ch.doa_budget(fi)
        fi, rb, db, pw = fi[keep], rb[keep], db[keep], pw[keep]
        snr = 10 * np.log10(pw / noise[fi, rb, db])
        v_w = ch.velocity_axis_mps[db]
        x = cell_snapshots(rd, rb, db, ch.detect.cell_half, frame=fi)
        ula = x[:, ch.ula_tx, ch.ula_rx, :]                    # (D, n_ula, L)
        orders = self.candidate_orders(float(np.max(np.abs(odo), initial=0.0)))
        n_d, n_m = len(fi), len(orders)
        v_m = v_w[:, None] + 2 * self.v_max * orders[None, :]  # (D, M)
        comp = compensate_tdm_velocity(np.repeat(ula, n_m, axis=0), v_m.reshape(-1),
                                       self.radar.wavelength_m, ch.slot_times_s, ch.ula_tx)
        o = ch.doa
        ang = np.full(n_d * n_m, np.nan)
        if n_d:
            ang = doa_angles(comp, ch.ula_pos, 1, o.n_signals, ch.grid_deg, method=o.method,
                             forward_backward=o.forward_backward, subarray=o.subarray,
                             loading=o.loading,
                             backend="torch" if o.method == "music" and o.loading == 0 else "numpy")[:, 0]
        ang = ang.reshape(n_d, n_m)
        resid = np.abs(v_m - static_radial_velocity(np.nan_to_num(ang), 1.0) * odo[fi][:, None])
        resid = np.where(np.isfinite(ang), resid, np.inf)
        best = np.argmin(resid, axis=1) if n_m else np.zeros(0, int)
        rows = np.arange(n_d)
        angle = ang[rows, best]
        v = v_m[rows, best]
        # ego speed per frame from the radar (RANSAC), static = on its Doppler curve
        ego_speed = np.full(len(frames), np.nan)
        n_static = np.zeros(len(frames), dtype=np.int64)
        static = np.zeros(n_d, dtype=bool)
        starts = np.searchsorted(fi, np.arange(len(frames) + 1))
        for f in range(len(frames)):      # one RANSAC fit per frame (sklearn)
            sl = slice(starts[f], starts[f + 1])
            ok = np.isfinite(angle[sl])
            if ok.sum() >= self.ego.min_inliers:
                speed, _ = estimate_ego_speed(v[sl][ok], angle[sl][ok],
                                              threshold_mps=self.ego.ransac_threshold_mps,
                                              min_inliers=self.ego.min_inliers,
                                              seed=self.ego.seed)
                ego_speed[f] = speed
            ref = ego_speed[f] if np.isfinite(ego_speed[f]) else odo[f]
            st_ = np.abs(v[sl] - static_radial_velocity(np.nan_to_num(angle[sl]), ref)) \
                <= self.ego.static_tolerance_mps
            static[sl] = st_ & ok
            n_static[f] = int(static[sl].sum())
        rng_m = ch.range_axis_m[rb]
        th = np.radians(angle)
        det = pd.DataFrame({
            "frame": frames[fi], "range_bin": rb.astype(np.int64), "doppler_bin": db.astype(np.int64),
            "range_m": rng_m, "velocity_wrapped_mps": v_w,
            "ambiguity_order": orders[best] if n_m else np.zeros(0, np.int64),
            "velocity_mps": v, "angle_deg": angle, "power": pw, "snr_db": snr, "static": static,
            "x_vehicle_m": rng_m * np.sin(th), "y_vehicle_m": rng_m * np.cos(th),
        }, columns=list(DRIVING_DETECTION_COLUMNS))
        ego = pd.DataFrame({"frame": frames, "odometry_mps": odo, "ego_speed_mps": ego_speed,
                            "n_detections": np.diff(starts), "n_static": n_static},
                           columns=list(EGO_COLUMNS))
        return DrivingBatch(det, ego, power if keep_maps else None,
                            threshold if keep_maps else None)
