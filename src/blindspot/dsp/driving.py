"""The detection chain on a moving car: range-Doppler, CFAR, Doppler unwrapping with the ego
speed, TDM-MIMO compensation with the unwrapped velocity, angles, ego-motion, static clutter
removal on the ego-motion Doppler curve, points in the vehicle frame.

Per batch of frames (every step vectorised over the batch's detections):

1. Range and Doppler FFTs, detection map, CFAR and local maxima: the steps of
   :class:`blindspot.dsp.chain.DetectionChain` (same configuration groups). With
   ``ego_motion.peak_search: range_doppler_angle`` the local maxima are taken in range, Doppler
   and angle together instead (:func:`~blindspot.dsp.detections.angle_peaks` on the strongest
   ``max_candidates`` CFAR cells of each frame), so a weak target beside a strong one at
   another angle keeps its cell.
2. The ``max_detections`` strongest peaks of each frame get angles (the static world gives most
   of them: the ego-motion fit needs them).
3. Ambiguity order (:func:`unwrap_and_angles`): the Doppler bin gives v modulo 2 v_max. For
   each candidate order m the snapshots are TDM-compensated with ``v_m = v_wrapped + 2 m v_max``
   (:func:`~blindspot.dsp.doppler_compensation.compensate_tdm_velocity`) and a Bartlett scan
   gives ``theta_m``; the order kept is the one whose velocity is nearest the static world's at
   its own angle, ``|v_m + v_odo cos(theta_m)|`` smallest: the order
   :func:`~blindspot.dsp.ego_motion.unwrap_doppler` chooses at the angle found under it. A
   wrong order compensates with a phase error ``2 pi m t_k / T_loop`` that shifts the angle by
   ~3 deg per order; the velocity it implies is ``2 m v_max`` away from the curve, so it loses.
   The angle is then the configured estimator's (MUSIC) with the chosen velocity.
4. Ego-motion from the radar: :func:`~blindspot.dsp.ego_motion.estimate_sensor_velocity`
   (RANSAC, Kellner et al. 2013) per frame gives the radar's (v_x, v_y), hence the speed and,
   with the radar's lever arm from the rear axle, the yaw rate ``-v_x / l``; detections within
   ``static_tolerance_mps`` of ``-(v_x sin theta + v_y cos theta)`` are static (clutter on a
   moving car), the others moving.
5. Points ``x = R sin(theta)``, ``y = R cos(theta)`` in the vehicle frame (radar at the bumper,
   boresight +y); the world frame needs the ego pose (:func:`blindspot.radar.driving.vehicle_to_world`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
import scipy.fft

from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.detections import ANGLE_FFT, angle_peaks, fft_beam_angle_deg, rank_in_frame
from blindspot.dsp.doa import doa_angles
from blindspot.dsp.doppler_compensation import compensate_tdm_velocity
from blindspot.dsp.ego_motion import (
    EgoMotionConfig, ego_motion_std, estimate_sensor_velocity, static_radial_velocity,
)
from blindspot.dsp.snapshots import cell_snapshots
from blindspot.radar.array import VirtualArray
from blindspot.radar.config import RadarConfig

ORDER_GRID_DEG = np.arange(-80.0, 80.01, 0.5)   # Bartlett grid of the order choice
BARTLETT_CHUNK = 256                            # snapshots per GEMM of the order choice's scan
# unwrap_and_angles with peak_centre: the estimator's peak must lie this close to the angle of
# the range-Doppler-angle maximum (the Hann-tapered 86-element beam's half-power width at
# boresight is about 1.9 deg; the MUSIC peak of the same return lies well inside it)
HINT_TOLERANCE_DEG = 2.0


def unwrap_and_angles(ula: np.ndarray, v_wrapped: np.ndarray, odometry_mps: np.ndarray,
                      chain: DetectionChain, v_max_mps: float, *,
                      peak_centre: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Doppler ambiguity order, unwrapped radial velocity and angle of each detection.

    ula: (D, n_ula, L) snapshots on the ULA elements; v_wrapped: (D,) the Doppler bins'
    velocities in [-v_max, v_max); odometry_mps: (D,) the ego speed each detection's frame
    unwraps with; chain: the configured :class:`DetectionChain` (array, slot times, DOA).

    For every candidate order m (those that can reach ``-v cos(theta)`` +- v_max), the snapshots
    are compensated with ``v_m = v_wrapped + 2 m v_max`` and a Bartlett beam scan
    (``sum_l |a(theta)^H x_l|^2`` on a 0.5 deg grid, cheap) gives ``theta_m``; the order kept
    minimises ``|v_m + v_odo cos(theta_m)|`` (:func:`~blindspot.dsp.ego_motion.unwrap_doppler` at
    the angle found under that order). The final angle is the configured estimator (MUSIC) on
    the snapshots compensated with the chosen velocity: its first peak (``doa.peak_order``), or,
    with ``peak_centre`` (the index of each detection's own cell along L; detections chosen by the
    range-Doppler-angle rule), the peak nearest the angle at which the cell is a
    range-Doppler-angle maximum (:func:`~blindspot.dsp.detections.angle_peaks` on the same
    snapshots), within ``HINT_TOLERANCE_DEG`` (NaN beyond it, or where no peak qualifies): a
    cell on a parked car's flank is kept for the child in it, whose angle is not the cell's
    strongest.

    Returns (order (D,) int64, velocity (D,) m/s, angle (D,) deg, NaN without a peak).
    """
    d = len(v_wrapped)
    if d == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    order, v = _choose_order(ula, v_wrapped, odometry_mps, chain, v_max_mps,
                             lambda comp: _bartlett_angles(comp, chain), ORDER_GRID_DEG)
    rows = np.arange(d)
    x = compensate_tdm_velocity(ula, v, chain.radar.wavelength_m, chain.slot_times_s,
                                chain.ula_tx)
    o = chain.doa
    n_targets = 1 if peak_centre is None else max(o.n_signals, 1)
    # with peak_centre every one of the n_signals peaks is a candidate and the hint picks one:
    # their order does not matter, so the power fit is skipped
    peaks = doa_angles(x, chain.ula_pos, n_targets, o.n_signals, chain.grid_deg, method=o.method,
                       forward_backward=o.forward_backward, subarray=o.subarray,
                       loading=o.loading,
                       peak_order=o.peak_order if peak_centre is None else "spectrum")
    if peak_centre is None:
        angle = peaks[:, 0]
    else:
        _, hint = angle_peaks(x, peak_centre, chain.array.spacing_wl)
        off = np.abs(np.nan_to_num(peaks, nan=np.inf) - hint[:, None])
        near = np.argmin(off, axis=1)
        angle = np.where(off[rows, near] <= HINT_TOLERANCE_DEG, peaks[rows, near], np.nan)
    return order, v, angle


def _choose_order(ula: np.ndarray, v_wrapped: np.ndarray, odometry_mps: np.ndarray,
                  chain: DetectionChain, v_max_mps: float, scan,
                  scan_grid_deg: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The Doppler ambiguity order of each detection and its unwrapped velocity, (D,) int64 and
    (D,) m/s: for every order m that can reach the static world, the snapshots ``ula`` (D, E, L)
    are TDM-compensated with ``v_m = v_wrapped + 2 m v_max`` and ``scan`` maps them,
    (K, E, L), to angles (K,) deg; the order kept minimises ``|v_m + v_odo cos(theta_m)|``
    (module docstring, step 3).

    ``scan_grid_deg``: the angles ``scan`` can return, if known. Then an order whose residual
    is, at every one of them, larger than another order's residual at its worst one (by more
    than 1e-9 m/s, far above rounding) cannot be kept whatever the scan says, and is not
    scanned, nor is a detection left with one order: the same choice, for a fraction of the
    scans (the orders far from the static world's velocities at the ego's speed)."""
    d = len(v_wrapped)
    odo = np.asarray(odometry_mps, dtype=float)
    lo = int(np.floor((-np.max(np.abs(odo)) - 2 * v_max_mps) / (2 * v_max_mps)))
    orders = np.arange(lo, 2)
    v_m = v_wrapped[:, None] + 2 * v_max_mps * orders[None, :]               # (D, M)
    if scan_grid_deg is None:
        need = np.ones(v_m.shape, dtype=bool)
    else:                               # each order's best and worst residual over the grid
        s = static_radial_velocity(np.asarray(scan_grid_deg, float), 1.0)   # (G,)
        spread = np.abs(v_m[:, :, None] - s[None, None, :] * odo[:, None, None])
        need = spread.min(axis=2) <= spread.max(axis=2).min(axis=1)[:, None] + 1e-9
    # a detection left with one order takes it unscanned
    scanned = need & (need.sum(axis=1) > 1)[:, None]
    di, mi = np.nonzero(scanned)
    theta = np.full(v_m.shape, np.nan)
    if di.size:
        comp = compensate_tdm_velocity(ula[di], v_m[di, mi], chain.radar.wavelength_m,
                                       chain.slot_times_s, chain.ula_tx)      # (K, E, L)
        theta[di, mi] = scan(comp)
    resid = np.where(scanned, np.abs(v_m - static_radial_velocity(theta, 1.0) * odo[:, None]),
                     np.where(need, 0.0, np.inf))
    best = np.argmin(resid, axis=1)
    return orders[best].astype(np.int64), v_m[np.arange(d), best]


def _bartlett_angles(comp: np.ndarray, chain: DetectionChain) -> np.ndarray:
    """(K,) deg: the Bartlett beam's peak on ``ORDER_GRID_DEG`` of snapshots (K, E, L), summed
    over the L cells."""
    from blindspot.dsp.doa import steering_matrix

    a = steering_matrix(chain.ula_pos, ORDER_GRID_DEG).conj().T.astype(np.complex64)  # (G, E)
    # (G, E) x (E, K*L) GEMMs (a stacked matmul over K would take numpy's slow loop), in chunks
    # of BARTLETT_CHUNK snapshots so that each beam's |z|^2 is summed while in cache (the whole
    # (G, K, L) product went through memory three times: 3.5 x the time; the same bytes)
    n_e, n_l = comp.shape[1], comp.shape[2]
    flat = np.ascontiguousarray(comp.astype(np.complex64).transpose(1, 0, 2)).reshape(n_e, -1)
    beam = np.empty((len(ORDER_GRID_DEG), comp.shape[0]), np.float32)
    for lo in range(0, comp.shape[0], BARTLETT_CHUNK):
        hi = min(lo + BARTLETT_CHUNK, comp.shape[0])
        z = (a @ flat[:, lo * n_l:hi * n_l]).reshape(len(ORDER_GRID_DEG), -1, n_l)  # (G, k, L)
        beam[:, lo:hi] = (z.real ** 2 + z.imag ** 2).sum(-1)                     # (G, k)
    return ORDER_GRID_DEG[np.argmax(beam, axis=0)]


def _fft_angles(comp: np.ndarray, spacing_wl: float) -> np.ndarray:
    """(K,) deg: the peak of a 256-point FFT beam of the first cell of snapshots (K, E, L) on a
    uniform linear array of element spacing ``spacing_wl`` wavelengths."""
    z = scipy.fft.fft(comp[:, :, 0].astype(np.complex64), n=ANGLE_FFT, axis=-1)
    return fft_beam_angle_deg(np.argmax(z.real ** 2 + z.imag ** 2, axis=-1), ANGLE_FFT,
                              spacing_wl)


def angle_peak_candidates(ula: np.ndarray, v_wrapped: np.ndarray, odometry_mps: np.ndarray,
                          chain: DetectionChain, v_max_mps: float, centre: int) -> np.ndarray:
    """(D,) bool: the candidate cells that are range-Doppler-angle maxima
    (:func:`~blindspot.dsp.detections.angle_peaks`), each TDM-compensated with its unwrapped
    velocity.

    ula: (D, E, L) snapshots of each candidate's neighbourhood on the ULA elements (its own
    cell at index ``centre`` of L); v_wrapped, odometry_mps: (D,) m/s, as for
    :func:`unwrap_and_angles`.

    The Doppler ambiguity order is chosen by :func:`unwrap_and_angles`' rule (the order whose
    velocity lies nearest the static world's at the angle found under it), with the angle from
    a 256-point FFT beam of the candidate's own cell instead of the 0.5 deg Bartlett scan of
    its whole neighbourhood (every CFAR cell is a candidate, so the scan is kept cheap). The
    order matters: the TX slots of the ULA's elements interleave, so a wrong order leaves a
    phase that repeats across the array and splits a strong target's beam into lobes far above
    the taper's sidelobes, which then mask a weak target beside it.
    """
    if len(v_wrapped) == 0:
        return np.zeros(0, dtype=bool)
    spacing = chain.array.spacing_wl
    _, v = _choose_order(ula[:, :, centre:centre + 1], v_wrapped, odometry_mps, chain, v_max_mps,
                         lambda comp: _fft_angles(comp, spacing))
    x = compensate_tdm_velocity(ula, v, chain.radar.wavelength_m, chain.slot_times_s,
                                chain.ula_tx)
    keep, _ = angle_peaks(x, centre, spacing)
    return keep


DRIVING_DETECTION_COLUMNS = (
    "frame", "range_bin", "doppler_bin", "range_m", "velocity_wrapped_mps", "ambiguity_order",
    "velocity_mps", "angle_deg", "power", "snr_db", "static", "x_vehicle_m", "y_vehicle_m",
)
EGO_COLUMNS = ("frame", "odometry_mps", "ego_speed_mps", "yaw_rate_deg_s", "speed_sd_theory_mps",
               "yaw_rate_sd_theory_deg_s", "n_detections", "n_static")


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
                 ego: EgoMotionConfig, rear_axle_to_radar_m: float | None = None):
        """``rear_axle_to_radar_m``: the radar's distance ahead of the rear axle (Kellner et al.
        2013); with it each frame's yaw rate is estimated too (NaN without)."""
        self.lever_m = rear_axle_to_radar_m
        base = DetectionChain.from_config(radar, array, cfar, doa, detect)
        # the driving chain's own range window and angle budget (static detections are wanted)
        self.base = DetectionChain(radar, array, base.cfar, base.doa,
                                   replace(base.detect, max_range_m=ego.max_range_m,
                                           max_detections=ego.max_detections))
        self.radar, self.ego = radar, ego
        self.v_max = radar.max_velocity_mps

    def _angle_peaks(self, rd: np.ndarray, fi: np.ndarray, rb: np.ndarray, db: np.ndarray,
                     pw: np.ndarray, odo: np.ndarray) -> tuple[np.ndarray, ...]:
        """The candidates (sorted by frame, strongest first) that are range-Doppler-angle peaks
        (:func:`angle_peak_candidates`): the strongest ``max_candidates`` of each frame with
        their neighbourhood cells (``detect.cell_half``) on the ULA elements; ``odo`` (F,) the
        frames' odometry speeds."""
        ch = self.base
        cand = rank_in_frame(fi) < self.ego.max_candidates
        fi, rb, db, pw = fi[cand], rb[cand], db[cand], pw[cand]
        ula = cell_snapshots(rd, rb, db, ch.detect.cell_half, frame=fi,
                             elements=(ch.ula_tx, ch.ula_rx))          # (D, E, L), centre first
        peak = angle_peak_candidates(ula, ch.velocity_axis_mps[db], odo[fi], ch, self.v_max, 0)
        return fi[peak], rb[peak], db[peak], pw[peak]

    def process_batch(self, cubes: np.ndarray, odometry_mps: np.ndarray, frames: np.ndarray,
                      *, keep_maps: bool = False) -> DrivingBatch:
        """cubes (F, chirps, tx, rx, samples), odometry speed (F,) m/s, frame numbers (F,)."""
        ch = self.base
        odo = np.asarray(odometry_mps, dtype=float)
        frames = np.asarray(frames, dtype=np.int64)
        rd, _ = ch.range_doppler(cubes)
        power = ch.detection_map(rd)
        mask, threshold, noise = ch.run_cfar(power)
        angle_rule = self.ego.peak_search == "range_doppler_angle"
        if angle_rule:                                       # every CFAR cell a candidate
            fi, rb, db = np.nonzero(mask & ch.range_ok[:, None])
        else:
            fi, rb, db = ch.select_cells(power, mask)
        pw = power[fi, rb, db]
        order = np.lexsort((-pw, fi))                        # per frame strongest first
        fi, rb, db, pw = fi[order], rb[order], db[order], pw[order]
        if angle_rule:
            fi, rb, db, pw = self._angle_peaks(rd, fi, rb, db, pw, odo)
        keep = ch.doa_budget(fi)
        fi, rb, db, pw = fi[keep], rb[keep], db[keep], pw[keep]
        snr = 10 * np.log10(pw / noise[fi, rb, db])
        v_w = ch.velocity_axis_mps[db]
        x = cell_snapshots(rd, rb, db, ch.detect.cell_half, frame=fi)
        ula = x[:, ch.ula_tx, ch.ula_rx, :]                    # (D, n_ula, L)
        order_m, v, angle = unwrap_and_angles(ula, v_w, odo[fi], ch, self.v_max,
                                              peak_centre=0 if angle_rule else None)
        n_d = len(fi)
        # ego speed (and yaw rate) per frame from the radar (RANSAC, Kellner et al. 2013),
        # static = on its Doppler curve -(v_x sin theta + v_y cos theta)
        n_f = len(frames)
        ego_speed, v_lat = np.full(n_f, np.nan), np.full(n_f, np.nan)
        sd_v, sd_w = np.full(n_f, np.nan), np.full(n_f, np.nan)
        n_static = np.zeros(n_f, dtype=np.int64)
        static = np.zeros(n_d, dtype=bool)
        starts = np.searchsorted(fi, np.arange(n_f + 1))
        for f in range(n_f):      # one RANSAC fit per frame (sklearn)
            sl = slice(starts[f], starts[f + 1])
            ok = np.isfinite(angle[sl])
            if ok.sum() >= self.ego.min_inliers:
                vx, vy, inl = estimate_sensor_velocity(v[sl][ok], angle[sl][ok],
                                                       threshold_mps=self.ego.ransac_threshold_mps,
                                                       min_inliers=self.ego.min_inliers,
                                                       seed=self.ego.seed)
                ego_speed[f], v_lat[f] = vy, vx
                if np.isfinite(vy) and self.lever_m is not None and inl.sum() > 2:
                    a_in = angle[sl][ok][inl]
                    res = v[sl][ok][inl] + vx * np.sin(np.radians(a_in)) + vy * np.cos(np.radians(a_in))
                    sd_v[f], sd_w[f] = ego_motion_std(a_in, float(np.sqrt(np.sum(res**2) / (inl.sum() - 2))),
                                                      self.lever_m)
            fit = np.isfinite(ego_speed[f])
            ref = ego_speed[f] if fit else odo[f]
            lat = v_lat[f] if fit else 0.0
            th = np.radians(np.nan_to_num(angle[sl]))
            curve = -(lat * np.sin(th) + ref * np.cos(th))
            st_ = np.abs(v[sl] - curve) <= self.ego.static_tolerance_mps
            static[sl] = st_ & ok
            n_static[f] = int(static[sl].sum())
        yaw = (np.degrees(-v_lat / self.lever_m) if self.lever_m is not None
               else np.full(n_f, np.nan))
        rng_m = ch.range_axis_m[rb]
        th = np.radians(angle)
        det = pd.DataFrame({
            "frame": frames[fi], "range_bin": rb.astype(np.int64), "doppler_bin": db.astype(np.int64),
            "range_m": rng_m, "velocity_wrapped_mps": v_w,
            "ambiguity_order": order_m,
            "velocity_mps": v, "angle_deg": angle, "power": pw, "snr_db": snr, "static": static,
            "x_vehicle_m": rng_m * np.sin(th), "y_vehicle_m": rng_m * np.cos(th),
        }, columns=list(DRIVING_DETECTION_COLUMNS))
        ego = pd.DataFrame({"frame": frames, "odometry_mps": odo, "ego_speed_mps": ego_speed,
                            "yaw_rate_deg_s": yaw, "speed_sd_theory_mps": sd_v,
                            "yaw_rate_sd_theory_deg_s": np.degrees(sd_w),
                            "n_detections": np.diff(starts), "n_static": n_static},
                           columns=list(EGO_COLUMNS))
        return DrivingBatch(det, ego, power if keep_maps else None,
                            threshold if keep_maps else None)
