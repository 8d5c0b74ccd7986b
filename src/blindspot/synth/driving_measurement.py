"""The fast measurement of driving scenes: every frame of many scenes through a reduced chain
that synthesises the whole range-Doppler map analytically (no 9 x 16 x 64 x 256 cube, no FFT),
with the moving-car steps of :class:`blindspot.dsp.driving.DrivingChain`.

Per batch of frames (every step vectorised over the batch):

1. Scatterers: the static world (every parked car's faces with its RCS, the roadside clutter
   lines: :func:`blindspot.radar.driving.static_scatterers`) and every pedestrian's body parts,
   relative to the moving radar (static points move at ``-v_ego``), with the occlusion loss of
   every parked car from the moving viewpoint; those in the field of view (+-75 deg, ahead of
   the bumper, inside the range window) are kept.
2. The detection map over the chain's whole range window and every Doppler bin: each
   scatterer's exact windowed range and Doppler response (:func:`blindspot.radar.rd_patch.
   patch_terms`, the DTFT at the bins, equal to the FFT of the simulated cube). The pedestrians'
   parts add coherently over the channels (:func:`~blindspot.radar.rd_patch.
   separable_channel_energy`); the static world's scatterers add in power (their mean
   energy over their relative phases), plus thermal noise drawn with the FFT's statistics
   (:func:`blindspot.synth.path_measurement.noncoherent_power`).
3. The chain's own CFAR on the whole map (so the parked cars' and kerb's returns raise the
   training-cell estimate around the pedestrian exactly where they fall), local maxima, the
   range window, strongest first and the ``max_detections`` budget per frame, as
   :meth:`DrivingChain.process_batch`. With ``ego_motion.peak_search: range_doppler_angle``
   every CFAR cell (the strongest ``max_candidates`` of a frame) gets its snapshots of step 4
   first, and those that are range-Doppler-angle maxima
   (:func:`blindspot.dsp.detections.angle_peaks`) go on to the budget.
4. Snapshots of each detection's 3 x 3 neighbourhood on the ULA elements: the coherent signal of
   the ``N_NEAR`` scatterers strongest in that cell plus noise correlated across cells as the
   windowed FFTs correlate it; Doppler ambiguity order with the odometry speed, TDM compensation
   with the unwrapped velocity and MUSIC (:func:`blindspot.dsp.driving.unwrap_and_angles`).
5. Static test on the ego-motion Doppler curve and the ego-compensated Doppler ("velocity over
   ground" along the line of sight): ``v_r - (-v_ego cos theta)``.

Outputs: every detection as a point (``POINT_COLUMNS``, vehicle and world frame, static flag,
truth label of the scatterer strongest in its cell, for scoring only), and the moving point of
each frame (``MEASURED_COLUMNS``): the largest cluster of the frame's detections off the static
curve (:func:`blindspot.dsp.points.group_points`, exactly as
:func:`blindspot.synth.driving_detection.points_from_detections` groups the full chain's),
attributed to the nearest pedestrian by truth (scoring only; at most one point per frame).
Grouping only the detections near the pedestrian (the former patch) would be truth-aided: on
CPFA it found a point in 0.38 of the frames where the full chain, grouping the whole frame,
finds one in 0.29.

Approximations against the full FMCW chain (``blindspot.synth.driving_detection``): (1) the
static scatterers' returns add in power, not in amplitude (no speckle between the points of
one car face; the CFAR training mean sees their mean energy); (2) the detection map's noise is
independent between cells (as in :mod:`blindspot.synth.path_measurement`); (3) a snapshot holds
the ``N_NEAR`` scatterers strongest in its cell (the others' sidelobes lie far below the noise);
(4) the static test uses the true ego speed (the full chain's RANSAC estimate is within
0.1 m/s RMS, well inside the 0.35 m/s tolerance); (5) with the range-Doppler-angle rule, a
candidate's neighbour cells carry the scatterers strongest in the candidate's cell and noise
drawn with the candidate's neighbourhood, so two neighbouring candidates see each other's cell
with different noise (the full chain's cells are one array). Validated against the full FMCW simulation of
the same frames (tests/synth/test_driving_measurement.py, slow; ``benchmarks/bench_driving.py
--scene cpfa cpna25 cpna75``): detection rate +1.5 %, and on the frames both chains have the
pedestrian's point (:func:`blindspot.synth.driving_detection.paired_point_statistics`) median
-3.8 %, p90 -0.3 %, range and angle error sd within 0.1 %.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.detections import local_maxima, rank_in_frame
from blindspot.dsp.driving import angle_peak_candidates, unwrap_and_angles
from blindspot.dsp.ego_motion import odometry_speed
from blindspot.dsp.points import group_points
from blindspot.parallel import parallel_map
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig
from blindspot.radar.driving import (
    FIELD_OF_VIEW_DEG, DrivingScene, ScenarioGroup, body_parts, car_polygons, ego_pose,
    frame_times, relative_velocity, static_scatterers, vehicle_to_world, world_to_vehicle,
)
from blindspot.radar.occlusion import segments_blocked
from blindspot.synth.path_measurement import _reduced_setup, noncoherent_power, point_scatterers

__all__ = ["MEASURED_COLUMNS", "POINT_COLUMNS", "DrivingMeasurement", "measure_driving",
           "first_seen_metrics",
           "measure_driving_scenes"]

MEASURED_COLUMNS = ("scene", "pedestrian", "frame", "time_s", "range_m", "angle_deg",
                    "velocity_mps", "snr_db", "n_detections", "x_vehicle_m", "y_vehicle_m",
                    "x_m", "y_m")
POINT_COLUMNS = ("scene", "frame", "time_s", "x_m", "y_m", "x_vehicle_m", "y_vehicle_m",
                 "range_m", "angle_deg", "velocity_mps", "velocity_wrapped_mps",
                 "ambiguity_order", "velocity_over_ground_mps", "static", "snr_db", "source")
N_NEAR = 12             # scatterers in a detection's snapshot (the strongest in its cell)


@dataclass(frozen=True)
class DrivingMeasurement:
    """``measured``: the pedestrian's point per (scene, pedestrian, frame) (MEASURED_COLUMNS);
    ``points``: every detection of every frame (POINT_COLUMNS)."""

    measured: pd.DataFrame
    points: pd.DataFrame


def _static_curve(angle_deg: np.ndarray, v_forward: np.ndarray, v_lateral: np.ndarray
                  ) -> np.ndarray:
    """Radial velocity of the static world at ``angle_deg`` for a radar moving at (v_lateral,
    v_forward) in its own frame: ``-(v_x sin theta + v_y cos theta)`` (Kellner et al. 2013)."""
    th = np.radians(angle_deg)
    return -(v_lateral * np.sin(th) + v_forward * np.cos(th))


def _scene_scatterers(scene: DrivingScene, group: ScenarioGroup, radar: RadarConfig,
                      max_range_m: float, idx: np.ndarray):
    """Every scatterer of the frames ``idx`` of one scene relative to the moving radar.

    Returns times (F,), poses (F, 3), positions (F, S, 3) and velocities (F, S, 3) in the vehicle
    frame (m, m/s), rcs (S,) m^2, attenuation (F, S) dB, label (S,) (-1 static, p >= 0 body part
    of pedestrian p) and the in-view mask (F, S)."""
    t = frame_times(scene, radar.frame_period_s)[idx]
    pose = ego_pose(scene, group, t)                                     # (F, 3)
    sxyz, srcs, _ = static_scatterers(scene, group)                      # (K, 3)
    pxyz, pv, prcs, who = body_parts(scene, group, t)                    # (F, Q, 3)
    n_f = len(t)
    xyz = np.concatenate([np.broadcast_to(sxyz, (n_f,) + sxyz.shape), pxyz], axis=1)
    vel = np.concatenate([np.zeros((n_f, len(sxyz), 3)), pv], axis=1)
    rcs = np.concatenate([srcs, prcs])
    label = np.concatenate([np.full(len(srcs), -1), who])
    rel = world_to_vehicle(xyz[..., :2], pose[:, None, :])
    rel_v = relative_velocity(vel[..., :2], scene, group, t)            # minus the ego's velocity
    r = np.linalg.norm(rel, axis=-1)
    short = xyz[..., :2] - (xyz[..., :2] - pose[:, None, :2]) * (1e-3 / np.maximum(r, 1e-9))[..., None]
    hidden = segments_blocked(short, pose[:, None, :2], car_polygons(scene))
    att = np.where(hidden, group.occlusion_db, 0.0)
    az = np.degrees(np.arctan2(rel[..., 0], rel[..., 1]))
    view = (rel[..., 1] > 0.2) & (np.abs(az) <= FIELD_OF_VIEW_DEG) & (r <= max_range_m + 3.0)
    pos = np.concatenate([rel, xyz[..., 2:]], -1)
    v3 = np.concatenate([rel_v, np.zeros_like(rel_v[..., :1])], -1)
    return t, pose, pos, v3, rcs, att, label, view


def _compact(view: np.ndarray, *arrays):
    """Per frame, the in-view scatterers first; the arrays (F, S, ...) cut to the largest count.
    Returns the kept-slot mask (F, S') and the arrays."""
    order = np.argsort(~view, axis=1, kind="stable")
    n = int(view.sum(1).max()) if view.size else 0
    order = order[:, :max(n, 1)]
    out = [np.take_along_axis(a, order.reshape(order.shape + (1,) * (a.ndim - 2)), axis=1)
           for a in arrays]
    return np.take_along_axis(view, order, axis=1), out


OVERSAMPLE = 128        # table of a window's response per 1/128 bin (power error < 0.1 %)


def _response_table(window: np.ndarray) -> np.ndarray:
    """(N * OVERSAMPLE,) power response of a window: ``|sum_i w_i exp(-j 2 pi q i / (N OS))|^2``,
    the windowed DFT of a unit tone at ``-q / OVERSAMPLE`` bins from the bin (FFT, zero-padded)."""
    f = np.fft.fft(np.asarray(window, dtype=np.float64), window.shape[0] * OVERSAMPLE)
    return f.real ** 2 + f.imag ** 2


def _tone_power(table: np.ndarray, n: int, nu: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """|windowed DFT|^2 of unit tones at ``nu`` (...) cycles/sample at the integer bins
    ``bins`` (broadcast against nu), from :func:`_response_table` (nearest 1/OVERSAMPLE bin)."""
    q = np.rint((bins - nu * n) * OVERSAMPLE).astype(np.int64) % table.size
    return table[q]


def _dtft_table(window: np.ndarray) -> np.ndarray:
    """(N * OVERSAMPLE + 1,) complex ``T(g) = sum_i w_i exp(j 2 pi g (i - (N - 1) / 2))`` on
    g = -1/2 .. 1/2 cycles/sample in steps of 1 / (N OVERSAMPLE): the window's DTFT without its
    linear phase, smooth enough for linear interpolation (:func:`_tone_dft_interpolated`)."""
    w = np.asarray(window, dtype=np.float64)
    n = w.shape[0]
    size = n * OVERSAMPLE
    y = np.fft.ifft(w, size) * size                  # sum_i w_i exp(+j 2 pi q i / size)
    q = np.arange(-size // 2, size // 2 + 1)
    return y[q % size] * np.exp(-2j * np.pi * (q / size) * (n - 1) / 2)


def _tone_dft_interpolated(table: np.ndarray, n: int, nu: np.ndarray, bins: np.ndarray
                           ) -> np.ndarray:
    """:func:`blindspot.radar.rd_patch.tone_dft` of unit tones at ``nu`` (...) cycles/sample at
    the integer bins ``bins`` (broadcast against nu) from :func:`_dtft_table`: one complex
    exponential per bin instead of one per sample (the window's DTFT at ``g = nu - bin / N``
    reduced to [-1/2, 1/2), its linear phase exact, the rest interpolated linearly; relative
    error below 1e-4 in the main lobe, tested against tone_dft)."""
    g = nu - bins / n
    g = g - np.round(g)
    pos = (g + 0.5) * (n * OVERSAMPLE)
    i0 = np.clip(np.floor(pos).astype(np.int64), 0, table.size - 2)
    frac = pos - i0
    t = table[i0] * (1.0 - frac) + table[i0 + 1] * frac
    return t * np.exp(1j * np.pi * g * (n - 1))


def _near_snapshots(setup, sc, bi, ki, di, tables, rng, dtft=None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(D, n_ula, L) snapshots of the detections (frame bi, row ki, Doppler column di) of the
    scatterers ``sc`` (B, S): the ``N_NEAR`` scatterers strongest in the cell, their exact signal
    (windowed DTFTs, channel phasors of the ULA elements) on the 3 x 3 neighbourhood plus noise
    correlated across cells as the windowed FFTs correlate it; and the (D,) index of the
    scatterer strongest in the cell. ``dtft``: the range and Doppler windows'
    :func:`_dtft_table`, to interpolate the windowed DTFTs (one exponential per bin instead of
    one per sample: the range-Doppler-angle rule's snapshots of every CFAR cell) instead of
    summing them exactly."""
    from blindspot.radar.rd_patch import (
        beat_frequency_hz, channel_phasors, doppler_frequency_hz, tone_dft,
    )

    chain, radar = setup.chain, setup.chain.radar
    hr, hd = chain.detect.cell_half
    n_rows, m, n = chain.range_axis_m.size, radar.n_chirps, radar.n_samples
    nu_r = beat_frequency_hz(sc.range_m, sc.velocity_mps, radar) / radar.adc_rate_hz  # (B, S)
    nu_d = doppler_frequency_hz(sc.velocity_mps, radar) * radar.loop_period_s
    amp = np.asarray(sc.amplitude)
    w = (np.abs(amp[bi]) ** 2 * _tone_power(tables[0], n, nu_r[bi], ki[:, None])
         * _tone_power(tables[1], m, nu_d[bi], (di - m // 2)[:, None]))            # (D, S)
    n_near = min(N_NEAR, w.shape[1])
    near = np.argpartition(-w, n_near - 1, axis=1)[:, :n_near]                      # (D, N)
    top = near[np.arange(len(bi)), np.argmax(np.take_along_axis(w, near, 1), axis=1)]
    take = lambda a: np.take_along_axis(a[bi], near, axis=1)  # noqa: E731
    if dtft is None:
        r3 = tone_dft(take(nu_r), (ki - hr)[:, None], 2 * hr + 1, setup.range_window)
        d3 = tone_dft(take(nu_d), (di - m // 2 - hd)[:, None], 2 * hd + 1, setup.doppler_window)
    else:
        r3 = _tone_dft_interpolated(dtft[0], n, take(nu_r)[..., None],
                                    (ki - hr)[:, None, None] + np.arange(2 * hr + 1))
        d3 = _tone_dft_interpolated(dtft[1], m, take(nu_d)[..., None],
                                    (di - m // 2 - hd)[:, None, None] + np.arange(2 * hd + 1))
    r3 = r3 * take(amp)[..., None]                                                  # (D, N, 3)
    if near.size > np.size(sc.velocity_mps):
        # more (detection, scatterer) pairs than scatterers: each scatterer's phasors once,
        # then gathered (the same elementwise values, so the same bytes)
        c_ula = channel_phasors(sc.velocity_mps, sc.azimuth_rad, radar, chain.array, "ula",
                                sc.elevation_rad)[bi[:, None], near]                # (D, N, E)
    else:
        el = None if sc.elevation_rad is None else take(sc.elevation_rad)
        c_ula = channel_phasors(take(sc.velocity_mps), take(sc.azimuth_rad), radar, chain.array,
                                "ula", el)                                          # (D, N, E)
    dr, dd = np.meshgrid(np.arange(-hr, hr + 1), np.arange(-hd, hd + 1), indexing="ij")
    dr, dd = dr.ravel(), dd.ravel()
    rows = np.clip(ki[:, None] + dr, 0, n_rows - 1)                                 # as the chain
    coef = (np.take_along_axis(r3, (rows - ki[:, None] + hr)[:, None, :], axis=2)
            * d3[:, :, dd + hd])                                                    # (D, N, L)
    x = c_ula.transpose(0, 2, 1) @ coef                                             # (D, E, L)
    n_el, n_l = x.shape[1], dr.size
    z = rng.standard_normal((len(bi), n_el, n_l, 2)).view(np.complex128)[..., 0]
    z *= np.sqrt(setup.sample_noise_power / 2.0)
    blk = z @ setup.block_chol.T
    cell = (rows - ki[:, None] + hr) * (2 * hd + 1) + (dd + hd)
    return x + np.take_along_axis(blk, cell[:, None, :], axis=2), top


def _centre_cell(chain: DetectionChain) -> int:
    """Index of a detection's own cell along the L axis of :func:`_near_snapshots` (the
    neighbourhood in (range, Doppler) row-major order, not centre first)."""
    hr, hd = chain.detect.cell_half
    return hr * (2 * hd + 1) + hd


_BATCH_STATE: dict | None = None    # measure_driving's inputs, read by _measure_batch


def _measure_batch(span: tuple[int, int, int]) -> dict[str, np.ndarray] | None:
    """Steps 2-5 of the module docstring for the frames ``lo:hi`` (batch ``b``) of the flat
    scatterer table in ``_BATCH_STATE``: every detection's columns (None without detections)."""
    from blindspot.radar.rd_patch import (
        PointScatterers, beat_frequency_hz, doppler_frequency_hz, patch_terms,
        separable_channel_energy,
    )

    b, lo, hi = span
    st = _BATCH_STATE
    setup, chain, radar, ego, n_q = st["setup"], st["chain"], st["radar"], st["ego"], st["n_q"]
    tables = st["tables"]
    # the batch's own slots: the table is padded to the widest scene of all (three pedestrians'
    # parts, the most cluttered street); padding slots (label -2, rcs 1e-30 m^2 at -400 dB)
    # add nothing above float64 rounding, and the coherent sum's cost grows as its square
    lab = st["label"][lo:hi]
    real = (lab != -2).any(axis=0)
    n_qb = int(np.flatnonzero(real[:n_q]).max(initial=-1)) + 1
    n_kb = int(np.flatnonzero(real[n_q:]).max(initial=-1)) + 1
    slots = np.concatenate([np.arange(max(n_qb, 1)), n_q + np.arange(max(n_kb, 1))])
    label = lab[:, slots]
    pos, v3 = st["pos"][lo:hi][:, slots], st["v3"][lo:hi][:, slots]
    rcs, att = st["rcs"][lo:hi][:, slots], st["att"][lo:hi][:, slots]
    n_q = max(n_qb, 1)
    n_rows, vmax, m = chain.range_axis_m.size, radar.max_velocity_mps, radar.n_chirps
    n_ch = radar.n_tx * radar.n_rx
    rows_k = np.arange(n_rows)
    cols_d = np.arange(m) - m // 2                       # zero-centred Doppler columns
    sc = point_scatterers(pos, v3, rcs, radar, output_scale=setup.output_scale)
    amp = sc.amplitude * 10 ** (-att / 20)
    sc = type(sc)(sc.range_m, sc.velocity_mps, sc.azimuth_rad, amp, sc.elevation_rad)
    # static world: power sum of every scatterer's exact response (mean over the points'
    # relative phases), from the windows' response tables; pedestrians: coherent sum
    nu_r = beat_frequency_hz(sc.range_m[:, n_q:], sc.velocity_mps[:, n_q:],
                             radar) / radar.adc_rate_hz
    nu_d = doppler_frequency_hz(sc.velocity_mps[:, n_q:], radar) * radar.loop_period_s
    p_r = (_tone_power(tables[0], radar.n_samples, nu_r[..., None], rows_k)
           * (np.abs(amp[:, n_q:]) ** 2)[..., None])                               # (B, S, K)
    p_d = _tone_power(tables[1], m, nu_d[..., None], cols_d)                        # (B, S, M)
    e_static = np.matmul(np.ascontiguousarray(p_r.transpose(0, 2, 1)), p_d) * n_ch
    mv = PointScatterers(sc.range_m[:, :n_q], sc.velocity_mps[:, :n_q],
                         sc.azimuth_rad[:, :n_q], amp[:, :n_q],
                         None if sc.elevation_rad is None else sc.elevation_rad[:, :n_q])
    r_t, d_t, c_all = patch_terms(mv, radar, chain.array, np.zeros(hi - lo, np.int64),
                                  n_rows, setup.range_window, setup.doppler_window, "all")
    e_move = separable_channel_energy(r_t, d_t, c_all)
    rng = np.random.default_rng(np.random.SeedSequence([ego.seed, 31, b]))
    power = noncoherent_power(rng, e_static + e_move, n_ch, setup.cell_noise_power)
    mask, _, noise = chain.run_cfar(power)
    keep = mask & chain.range_ok[None, :, None]
    angle_rule = ego.peak_search == "range_doppler_angle"
    if chain.detect.peak_only and not angle_rule:
        keep &= local_maxima(power)
    bi, ki, di = np.nonzero(keep)
    pw = power[bi, ki, di]
    o = np.lexsort((-pw, bi))                                       # per frame strongest first
    bi, ki, di, pw = bi[o], ki[o], di[o], pw[o]
    if angle_rule:      # every CFAR cell a candidate (strongest max_candidates), 3-D peaks kept
        cand = rank_in_frame(bi) < ego.max_candidates
        bi, ki, di, pw = bi[cand], ki[cand], di[cand], pw[cand]
        x, top = _near_snapshots(setup, sc, bi, ki, di, tables, rng, st["dtft"])
        peak = angle_peak_candidates(x, chain.velocity_axis_mps[di], st["odo"][lo:hi][bi], chain,
                                     vmax, _centre_cell(chain))
        bi, ki, di, pw, x, top = bi[peak], ki[peak], di[peak], pw[peak], x[peak], top[peak]
    sel = chain.doa_budget(bi)
    bi, ki, di, pw = bi[sel], ki[sel], di[sel], pw[sel]
    if not bi.size:
        return None
    snr = 10 * np.log10(pw / noise[bi, ki, di])
    if angle_rule:
        x, top = x[sel], top[sel]
    else:
        x, top = _near_snapshots(setup, sc, bi, ki, di, tables, rng)
    v_w = chain.velocity_axis_mps[di]
    order, v, angle = unwrap_and_angles(x, v_w, st["odo"][lo:hi][bi], chain, vmax,
                                        peak_centre=_centre_cell(chain) if angle_rule else None)
    off = v - _static_curve(np.nan_to_num(angle), st["speed"][lo:hi][bi],
                            st["v_lat"][lo:hi][bi])
    return {"row": ki, "bi": bi + lo, "rng": chain.range_axis_m[ki], "ang": angle, "v": v,
            "vw": v_w, "order": order, "off": off, "snr": snr, "src": label[bi, top]}


def measure_driving(scenes: list[DrivingScene], group: ScenarioGroup, radar: RadarConfig,
                    cfar, doa, detect, ego, *, adc_headroom_db: float = 60.0,
                    frames: dict[str, np.ndarray] | None = None, frames_per_batch: int = 48,
                    jobs: int = 1, progress: bool = False) -> DrivingMeasurement:
    """Every frame of ``scenes`` through the fast whole-map chain (module docstring).

    Args:
        scenes, group: driving scenes and their ``scenario`` group.
        radar: the driving profile; cfar, doa, detect: the chain's groups; ego: the
            ``ego_motion`` group (odometry model, budget, range window, static tolerance, seed).
        frames: optional {scene name: frame indices} to measure (default every frame).
        frames_per_batch: frames synthesised together (part of the random stream).
        jobs: worker processes over the batches (:func:`blindspot.parallel.parallel_map`;
            the result does not depend on it).

    Returns:
        :class:`DrivingMeasurement`: ``points`` one row per detection (POINT_COLUMNS; ``source``
        is the truth label, "static" or the pedestrian's name, for scoring only) and
        ``measured`` the frame's moving point (MEASURED_COLUMNS), attributed to the nearest
        pedestrian (at most one row per frame).
        Nothing is invented where the chain finds nothing.

    Raises:
        ValueError: frame indices outside a scene.
    """
    array = array_for(radar)
    base = DetectionChain.from_config(radar, array, cfar, doa, detect)
    chain = DetectionChain(radar, array, base.cfar, base.doa,
                           replace(base.detect, max_range_m=ego.max_range_m,
                                   max_detections=ego.max_detections))
    setup = _reduced_setup(chain, 8, adc_headroom_db)     # (core rows unused: whole maps)
    # ---- every scatterer of every frame, one flat table (padded along the scatterer axis)
    per = []
    for si, sc in enumerate(scenes):       # a few hundred scenes; each vectorised over frames
        n_all = len(frame_times(sc, radar.frame_period_s))
        idx = np.arange(n_all) if frames is None or sc.name not in frames else \
            np.asarray(frames[sc.name], dtype=np.int64)
        if idx.size and (idx.min() < 0 or idx.max() >= n_all):
            raise ValueError(f"frames {idx.min()}..{idx.max()} outside scene {sc.name!r} "
                             f"(0..{n_all - 1})")
        if not idx.size:
            continue
        odo = odometry_speed(np.full(n_all, sc.speed_mps), ego.odometry_noise_mps,
                             ego.odometry_bias_mps,
                             np.random.default_rng(np.random.SeedSequence([sc.seed, 21])))[idx]
        t, pose, pos, v3, rcs, att, label, view = _scene_scatterers(sc, group, radar,
                                                                    ego.max_range_m, idx)
        rcs_f = np.broadcast_to(rcs, view.shape)
        lab_f = np.broadcast_to(label, view.shape)
        mov = label >= 0                      # the body parts keep their slots (coherent sum)
        keep, (s_pos, s_v3, s_rcs, s_att, s_lab) = _compact(
            view[:, ~mov], pos[:, ~mov], v3[:, ~mov], rcs_f[:, ~mov], att[:, ~mov], lab_f[:, ~mov])
        per.append(dict(si=si, idx=idx, t=t, pose=pose, odo=odo,
                        m_pos=pos[:, mov], m_v3=v3[:, mov], m_rcs=rcs_f[:, mov],
                        m_att=np.where(view[:, mov], att[:, mov], 400.0), m_label=lab_f[:, mov],
                        s_pos=s_pos, s_v3=s_v3, s_rcs=s_rcs, s_att=np.where(keep, s_att, 400.0),
                        s_label=np.where(keep, s_lab, -2)))
    if not per:
        return DrivingMeasurement(pd.DataFrame(columns=list(MEASURED_COLUMNS)),
                                  pd.DataFrame(columns=list(POINT_COLUMNS)))
    n_q = max(p["m_pos"].shape[1] for p in per)
    n_k = max(p["s_pos"].shape[1] for p in per)

    def cat(key, fill=0.0):
        width = n_q if key.startswith("m_") else n_k
        out = []
        for p in per:
            a = p[key]
            if key[:2] in ("m_", "s_"):
                pad = [(0, 0), (0, width - a.shape[1])] + [(0, 0)] * (a.ndim - 2)
                a = np.pad(a, pad, constant_values=fill)
            out.append(a)
        return np.concatenate(out)

    # moving scatterers (body parts) in the first n_q slots, the static world after them
    pos = np.concatenate([cat("m_pos", 1.0), cat("s_pos", 1.0)], 1)
    v3 = np.concatenate([cat("m_v3"), cat("s_v3")], 1)
    rcs = np.concatenate([cat("m_rcs", 1e-30), cat("s_rcs", 1e-30)], 1)
    att = np.concatenate([cat("m_att", 400.0), cat("s_att", 400.0)], 1)
    label = np.concatenate([cat("m_label", -2), cat("s_label", -2)], 1)
    t, pose, odo, fidx = cat("t"), cat("pose"), cat("odo"), cat("idx")
    scene_i = np.concatenate([np.full(len(p["idx"]), p["si"]) for p in per])
    speed = np.array([s.speed_mps for s in scenes])[scene_i]
    # the radar's lateral velocity -omega l (turning scenes; Kellner et al. 2013)
    v_lat = np.array([-np.radians(s.yaw_rate_deg_s) * group.ego.rear_axle_to_radar_m
                      for s in scenes])[scene_i]
    n = len(fidx)
    tables = (_response_table(setup.range_window), _response_table(setup.doppler_window))
    dtft = (_dtft_table(setup.range_window), _dtft_table(setup.doppler_window))
    # the batches are independent (each draws its own noise from SeedSequence([seed, 31, b])),
    # so worker processes (forked: they inherit this state) measure them in any order with the
    # same result as in this process
    global _BATCH_STATE
    _BATCH_STATE = dict(pos=pos, v3=v3, rcs=rcs, att=att, label=label, odo=odo, speed=speed,
                        v_lat=v_lat, n_q=n_q, setup=setup, chain=chain, radar=radar, ego=ego,
                        tables=tables, dtft=dtft)
    spans = [(b, lo, min(lo + frames_per_batch, n))
             for b, lo in enumerate(range(0, n, frames_per_batch))]
    try:
        parts = parallel_map(_measure_batch, spans, jobs,
                             progress="driving frames (fast)" if progress else None)
    finally:
        _BATCH_STATE = None
    keys = ("row", "bi", "rng", "ang", "v", "vw", "order", "off", "snr", "src")
    cols = {k: [p[k] for p in parts if p is not None] for k in keys}
    c = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}
    g = c["bi"].astype(np.int64)
    ok = np.isfinite(c["ang"])
    g, c = g[ok], {k: v[ok] for k, v in c.items()}
    th = np.radians(c["ang"])
    xv, yv = c["rng"] * np.sin(th), c["rng"] * np.cos(th)
    world = vehicle_to_world(np.stack([xv, yv], -1), pose[g])
    names = np.array([s.name for s in scenes], dtype=object)
    ped_names = {(i, p): s.pedestrians[p].name for i, s in enumerate(scenes)
                 for p in range(len(s.pedestrians))}
    src = np.array(["static" if int(l) < 0 else ped_names[(int(i), int(l))]
                    for i, l in zip(scene_i[g], c["src"])], dtype=object)   # noqa: E741
    tol = ego.static_tolerance_mps
    points = pd.DataFrame({
        "scene": names[scene_i[g]], "frame": fidx[g].astype(np.int64), "time_s": t[g],
        "x_m": world[:, 0], "y_m": world[:, 1], "x_vehicle_m": xv, "y_vehicle_m": yv,
        "range_m": c["rng"], "angle_deg": c["ang"], "velocity_mps": c["v"],
        "velocity_wrapped_mps": c["vw"], "ambiguity_order": c["order"].astype(np.int64),
        "velocity_over_ground_mps": c["off"], "static": np.abs(c["off"]) <= tol,
        "snr_db": c["snr"], "source": src}, columns=list(POINT_COLUMNS))
    # ---- the pedestrian's point per frame, grouped as the full chain's detections are
    # (blindspot.synth.driving_detection.points_from_detections): the largest cluster of the
    # frame's off-curve detections; it is attributed to the pedestrian nearest to it (truth,
    # for scoring), so a frame has at most one point
    meas = []
    pts = group_points(g, c["rng"], c["off"], c["ang"], c["snr"], tol, chain.detect.cluster_gap_m)
    if pts["frame"].size:
        f = pts["frame"]
        th = np.radians(pts["angle_deg"])
        xv_p, yv_p = pts["range_m"] * np.sin(th), pts["range_m"] * np.cos(th)
        n_ped = max(len(s.pedestrians) for s in scenes)
        lab = label[f]                                                    # (P', S)
        centre = np.stack([np.stack([np.where(lab == p, pos[f, :, 0], 0).sum(1),
                                     np.where(lab == p, pos[f, :, 1], 0).sum(1)], -1)
                           for p in range(n_ped)], -1)                                # (P', 2, n_ped)
        n_parts = np.stack([(lab == p).sum(1) for p in range(n_ped)], 1)             # (P', n_ped)
        centre = centre / np.maximum(n_parts, 1)[:, None, :]                          # (P', 2, n_ped)
        d = np.hypot(centre[:, 0] - xv_p[:, None], centre[:, 1] - yv_p[:, None])
        d = np.where(n_parts > 0, d, np.inf)
        who = np.argmin(d, axis=1)
        has = np.isfinite(d.min(1))
        w = vehicle_to_world(np.stack([xv_p, yv_p], -1), pose[f])
        meas.append(pd.DataFrame({
            "scene": names[scene_i[f]],
            "pedestrian": [ped_names[(int(i), int(p))] for i, p in zip(scene_i[f], who)],
            "frame": fidx[f].astype(np.int64), "time_s": t[f], "range_m": pts["range_m"],
            "angle_deg": pts["angle_deg"],
            "velocity_mps": pts["velocity_mps"] + _static_curve(pts["angle_deg"], speed[f],
                                                                v_lat[f]),
            "snr_db": pts["snr_db"], "n_detections": pts["n_detections"].astype(np.int64),
            "x_vehicle_m": xv_p, "y_vehicle_m": yv_p, "x_m": w[:, 0], "y_m": w[:, 1]},
            columns=list(MEASURED_COLUMNS))[has])
    measured = (pd.concat(meas, ignore_index=True) if meas
                else pd.DataFrame(columns=list(MEASURED_COLUMNS)))
    measured = measured.sort_values(["scene", "frame", "pedestrian"], kind="stable",
                                    ignore_index=True)
    return DrivingMeasurement(measured, points)


def measure_driving_scenes(scenes: list[DrivingScene], group: ScenarioGroup, radar: RadarConfig,
                           cfar, doa, detect, ego, *, adc_headroom_db: float = 60.0,
                           frames: dict[str, np.ndarray] | None = None,
                           progress: bool = False) -> pd.DataFrame:
    """The pedestrians' points (MEASURED_COLUMNS) of :func:`measure_driving` alone."""
    return measure_driving(scenes, group, radar, cfar, doa, detect, ego,
                           adc_headroom_db=adc_headroom_db, frames=frames,
                           progress=progress).measured


def first_seen_metrics(points: pd.DataFrame, measured: pd.DataFrame, truth: pd.DataFrame,
                       n_scenes: int) -> dict:
    """The driving_measure stage's metrics: how early each intruding Monte-Carlo pedestrian
    (``p0``) is first seen, per ego speed (time to collision without braking at its first
    point within 1.5 m of its truth), from its off-curve points only (static-looking ones
    dropped, as the clutter filter does) and from every point it returns (static-looking ones
    kept, what a tracker in the world frame can use), its detection rate while visible and the
    median error; the truth labels score, they feed nothing. ``points``, ``measured``: the
    stage's tables; ``truth``: data/driving/truth.parquet; ``n_scenes``: scenes measured."""
    # the pedestrian's own returns among every point (truth label, for scoring only), static-
    # looking ones included: the first within 1.5 m of the truth is when a world-frame tracker
    # could first see it
    own = points[points.source == "p0"].merge(
        truth[truth.pedestrian == "p0"][["scene", "frame", "x_m", "y_m", "ttc_s", "behaviour",
                                         "ego_speed_mps"]],
        on=["scene", "frame"], suffixes=("", "_t"))
    own = own[np.hypot(own.x_m - own.x_m_t, own.y_m - own.y_m_t) <= 1.5]
    mc_names = set(truth.scene[truth.set == "monte_carlo"])
    own = own[own.scene.isin(mc_names) & (own.behaviour == "cross") & (own.ttc_s > 0)]
    first_kept = own.groupby("scene").ttc_s.max()
    first_dropped = own[~own.static].groupby("scene").ttc_s.max()
    static_share = own.groupby("scene").static.mean()
    j = truth.merge(measured, on=["scene", "pedestrian", "frame"], how="left", suffixes=("", "_m"))
    err = np.hypot(j.x_m_m - j.x_m, j.y_m_m - j.y_m)
    j = j.assign(hit=err <= 1.5, error_m=err)
    mc = j[(j.set == "monte_carlo") & (j.pedestrian == "p0")]
    per_speed = {}
    for kmh, g in mc.groupby(mc.ego_speed_mps * 3.6):
        intr = g[(g.behaviour == "cross") & (g.ttc_s > 0)]
        first = intr[intr.hit].groupby("scene").ttc_s.max()          # earliest hit = largest TTC
        n_sc = intr.scene.nunique()
        vis = g[~g.occluded]
        kept = first_kept.reindex(intr.scene.unique()).dropna()
        dropped = first_dropped.reindex(intr.scene.unique()).dropna()
        per_speed[f"{kmh:.0f}"] = {
            "n_scenes_intruding": int(n_sc),
            "first_seen_ttc_s_median_static_dropped": (float(dropped.median()) if len(dropped)
                                                       else None),
            "first_seen_ttc_s_median_static_kept": float(kept.median()) if len(kept) else None,
            "seen_before_collision_rate_static_kept": float(len(kept) / n_sc) if n_sc else None,
            "static_share_of_own_points": (float(static_share.reindex(kept.index).mean())
                                           if len(kept) else None),
            "seen_before_collision_rate": float(len(first) / n_sc) if n_sc else None,
            "first_seen_ttc_s_median": float(first.median()) if len(first) else None,
            "detection_rate_visible": float(vis.hit.mean()) if len(vis) else None,
            "median_error_m": float(g.error_m[g.hit].median()) if g.hit.any() else None,
        }
    n_frames = points.groupby("scene").frame.nunique().sum()
    metrics = {"n_scenes": int(n_scenes), "n_points": int(len(measured)),
               "n_radar_points": int(len(points)),
               "static_points_per_frame": float(points.static.sum() / max(n_frames, 1)),
               "by_speed_kmh": per_speed}
    return metrics
