"""Pass synthetic pedestrian paths through the radar chain, point by point (paper section III).

Every truth point of a path becomes a walking pedestrian (the scene model's body: torso, head,
swinging arms and legs, from :mod:`blindspot.radar.scene`) seen by the FMCW radar in one frame;
the frame goes through range FFT, Doppler FFT, CA-CFAR, Doppler compensation, MUSIC and the
points step, and what comes out is the *measured* point: its range interpolated between the
0.5 m range bins (or quantised to them, ``detect.range_interpolation: none``), with the angle
error of MUSIC on a real body, or missing (NaN) when CFAR found nothing. This is
the measurement error the LSTM has to learn to live with.

Two ways to get there
---------------------
* ``full_chain=True``: the project's simulator (:class:`~blindspot.radar.simulator.FmcwSimulator`)
  builds each 64 x 12 x 16 x 256 cube and :class:`~blindspot.dsp.chain.DetectionChain` processes
  it. Exact, and a few frames/s on this machine: the reference.
* default, the *reduced* chain: the same scatterers give a range-Doppler *patch* around the
  pedestrian computed analytically (:mod:`blindspot.radar.rd_patch`: windowed DTFT at the bin
  frequencies, identical to the FFT of the simulated cube), with noise drawn with the FFT's exact
  statistics, and the chain's own batch-native steps (``run_cfar``, ``local_maxima``,
  ``order_detections`` and ``doa_budget``, ``angles``: TDM compensation and MUSIC of
  :mod:`blindspot.dsp.doa`, and ``group_points``) run on the patches of thousands of frames at
  once. See :func:`measure_paths` for what is exact and what is approximated; the test
  ``tests/synth/test_path_measurement.py`` shows the point-error statistics of both agree within
  10 % (measured: within 1 % for the paper's CFAR, 5 % for CA-CFAR at Pfa 1e-6), at 300-600
  frames/s on this 2-core machine (``benchmarks/bench_paths.py``).

Geometry and units follow the project: radar at the origin, boresight +y, x to the right, SI.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from blindspot.dsp.detections import local_maxima
from blindspot.dsp.points import group_points
from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig
from blindspot.radar.radar_equation import received_power_w
from blindspot.radar.rd_patch import PointScatterers
from blindspot.radar.scene import BodyPart, SceneConfig

__all__ = [
    "measure_paths",
    "PathMeasurement",
    "error_statistics",
    "PedestrianModel",
    "noncoherent_power",
    "cfar_on_patches",
    "path_kinematics",
    "body_scatterers",
    "point_scatterers",
]


# ------------------------------------------------------------------------------ the walker
@dataclass(frozen=True)
class PedestrianModel:
    """The scene model's walking body, detached from the scene's fixed route.

    Attributes:
        parts: body parts (RCS, height, lateral offset, swing amplitude and phase), as in
            ``conf/scene/*.yaml`` ``pedestrian.parts``.
        stride_length_m: distance walked per gait cycle; the limbs swing at speed / stride.
        radar_height_m: radar height above the ground (part heights are above the ground).
    """

    parts: tuple[BodyPart, ...]
    stride_length_m: float = 1.4
    radar_height_m: float = 0.5

    def __post_init__(self) -> None:
        if not self.parts:
            raise ValueError("PedestrianModel.parts: expected at least one body part, found none")
        if not (np.isfinite(self.stride_length_m) and self.stride_length_m > 0):
            raise ValueError("PedestrianModel.stride_length_m: expected > 0, found "
                             f"{self.stride_length_m}")

    @classmethod
    def from_scene(cls, scene: SceneConfig) -> PedestrianModel:
        """The body of a scene configuration (e.g. from ``load_scenes(conf/scene/paper.yaml)``)."""
        ped = scene.pedestrian
        return cls(parts=ped.parts, stride_length_m=ped.stride_length_m,
                   radar_height_m=scene.radar_height_m)

    @property
    def rcs_m2(self) -> np.ndarray:
        """(n_parts,) RCS of each part, m^2."""
        return 10.0 ** (np.array([p.rcs_dbsm for p in self.parts]) / 10.0)

    @property
    def n_parts(self) -> int:
        return len(self.parts)


def path_kinematics(paths: np.ndarray, frame_period_s: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, turn rate and walked distance along paths sampled at the frame period.

    Args:
        paths: (P, T, 2) body-centre positions (x, y), m, T >= 2, finite.
        frame_period_s: time between points, s.

    Returns:
        velocity (P, T, 2) m/s (second-order finite differences), turn_rate (P, T) rad/s
        (counter-clockwise positive, ``(v x a) / |v|^2``), distance (P, T) m walked since the
        first point (cumulative chord length).
    """
    xy = np.asarray(paths, dtype=np.float64)
    if xy.ndim != 3 or xy.shape[-1] != 2 or xy.shape[1] < 2:
        raise ValueError(f"paths: expected shape (P, T >= 2, 2), found {xy.shape}")
    if not np.all(np.isfinite(xy)):
        raise ValueError("paths: truth paths must be finite (NaN marks *measured* gaps only)")
    edge = 2 if xy.shape[1] >= 3 else 1
    vel = np.gradient(xy, frame_period_s, axis=1, edge_order=edge)
    acc = np.gradient(vel, frame_period_s, axis=1, edge_order=edge)
    speed2 = np.sum(vel**2, axis=-1)
    cross = vel[..., 0] * acc[..., 1] - vel[..., 1] * acc[..., 0]
    turn = np.divide(cross, speed2, out=np.zeros_like(cross), where=speed2 > 1e-12)
    step = np.linalg.norm(np.diff(xy, axis=1), axis=-1)
    dist = np.concatenate([np.zeros(xy.shape[:1] + (1,)), np.cumsum(step, axis=1)], axis=1)
    return vel, turn, dist


def body_scatterers(xy: np.ndarray, velocity: np.ndarray, turn_rate: np.ndarray,
                    gait_rad: np.ndarray, model: PedestrianModel
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of the body parts (the scene model's kinematics on any path).

    Each part sits ``lateral_m`` to the walker's left and swings ``swing_m sin(gait + phase)``
    along the walking direction; ``gait = 2 pi distance / stride_length`` (+ a per-path offset),
    so at constant speed it is the scene's ``2 pi (speed / stride) t``. Velocities include the
    swing rate and the rotation of the body frame at ``turn_rate``.

    Args:
        xy: (B, 2) body centre, m. velocity: (B, 2) m/s. turn_rate: (B,) rad/s.
        gait_rad: (B,) gait phase.

    Returns:
        position (B, n_parts, 3), velocity (B, n_parts, 3) relative to the radar (z up, the
        radar at ``radar_height_m``).
    """
    xy, velocity = np.asarray(xy, float), np.asarray(velocity, float)
    speed = np.linalg.norm(velocity, axis=-1)
    safe = np.where(speed > 1e-9, speed, 1.0)
    u = np.where((speed > 1e-9)[:, None], velocity / safe[:, None], [0.0, 1.0])[:, None, :]
    n = np.stack([-u[..., 1], u[..., 0]], axis=-1)                       # walker's left
    om = np.asarray(turn_rate, float)[:, None, None]
    lat = np.array([p.lateral_m for p in model.parts])[None, :, None]
    amp = np.array([p.swing_m for p in model.parts])[None, :]
    phase = np.radians([p.phase_deg for p in model.parts])[None, :]
    arg = np.asarray(gait_rad, float)[:, None] + phase                   # (B, n_parts)
    rate = (2.0 * np.pi * speed / model.stride_length_m)[:, None]
    d = (amp * np.sin(arg))[..., None]
    d_dot = (amp * rate * np.cos(arg))[..., None]
    pos_xy = xy[:, None, :] + d * u + lat * n
    vel_xy = velocity[:, None, :] + d_dot * u + d * om * n - lat * om * u
    z = np.array([p.height_m for p in model.parts]) - model.radar_height_m
    b, k = pos_xy.shape[:2]
    pos = np.concatenate([pos_xy, np.broadcast_to(z, (b, k))[..., None]], axis=-1)
    vel = np.concatenate([vel_xy, np.zeros((b, k, 1))], axis=-1)
    return pos, vel


def point_scatterers(position_m: np.ndarray, velocity_mps: np.ndarray, rcs_m2: np.ndarray,
                     radar: RadarConfig, *, output_scale: float = 1.0) -> PointScatterers:
    """3-D scatterers -> the range / radial velocity / direction / complex amplitude description
    of :mod:`blindspot.radar.rd_patch`, with the simulator's amplitude (radar equation, sqrt(W)
    times ``output_scale``) and carrier phase ``4 pi f0 R / c``.

    position_m, velocity_mps: (B, S, 3); rcs_m2: (S,) or (B, S)."""
    pos, vel = np.asarray(position_m, float), np.asarray(velocity_mps, float)
    rng = np.linalg.norm(pos, axis=-1)
    if np.any(rng <= 0):
        raise ValueError("point_scatterers: a scatterer sits at the radar (range 0)")
    u = pos / rng[..., None]
    v_r = np.einsum("bsd,bsd->bs", vel, u)
    amp = np.sqrt(received_power_w(radar, rcs_m2, rng)) * output_scale
    carrier = np.mod(4.0 * np.pi * radar.start_freq_hz * rng / SPEED_OF_LIGHT, 2.0 * np.pi)
    return PointScatterers(range_m=rng, velocity_mps=v_r,
                           azimuth_rad=np.arctan2(u[..., 0], u[..., 1]),
                           amplitude=amp * np.exp(1j * carrier),
                           elevation_rad=np.arcsin(np.clip(u[..., 2], -1.0, 1.0)))


# ------------------------------------------------------------------ reduced chain: detection
def noncoherent_power(rng: np.random.Generator, energy: np.ndarray, n_looks: int,
                      cell_noise_power: float) -> np.ndarray:
    """Draw the detection-map value of cells whose signal energy over ``n_looks`` channels is
    ``energy``: ``sum_c |s_c + n_c|^2`` with n_c ~ CN(0, sigma^2) independent over channels.

    Rotating the channel space so the signal lies along one axis, this is exactly
    ``|sqrt(E) + n|^2 + sigma^2 Gamma(n_looks - 1)`` (a non-central chi-square of 2 n_looks
    degrees of freedom): one complex normal and one gamma draw per cell instead of n_looks
    complex normals. energy: (...) W-units -> float64 (...)."""
    e = np.asarray(energy, dtype=np.float64)
    z = rng.standard_normal(e.shape + (2,))
    s = np.sqrt(cell_noise_power / 2.0)
    out = (np.sqrt(np.maximum(e, 0.0)) + s * z[..., 0]) ** 2 + (s * z[..., 1]) ** 2
    if n_looks > 1:
        out += cell_noise_power * rng.standard_gamma(n_looks - 1, size=e.shape)
    return out


def cfar_on_patches(power: np.ndarray, first_row: np.ndarray, n_rows_total: int,
                    half_rows: int, run_cfar) -> tuple[np.ndarray, np.ndarray]:
    """Run a 2-D CFAR (e.g. :meth:`blindspot.dsp.chain.DetectionChain.run_cfar`) on a batch of
    patches as if on the full map.

    Each frame's patch holds rows ``first_row[b] .. first_row[b] + K - 1`` of a map of
    ``n_rows_total`` range bins and *all* Doppler bins (so Doppler wraps as in the full map).
    Only the core rows ``[h, K - h)`` (``h = half_rows`` = guard + training half-width in range)
    are decided: their training windows lie inside the patch, so the result equals CFAR on the
    full map. Frames whose patches lie inside the map are stacked along range and processed in
    one call (rows of neighbouring frames only ever fall into the windows of the undecided
    border rows); frames whose patch crosses the first or last range bin are processed one by
    one on their existing rows, so the edge rule (fewer training cells, larger factor) is the
    full map's.

    Args:
        power: (B, K, M) detection-map patches.
        first_row: (B,) map row of each patch's first row (may be < 0 or run past the end).
        n_rows_total: number of range bins of the full map.
        half_rows: the CFAR window's range half-width, guard + train.
        run_cfar: callable (R, M) map -> (mask, threshold, noise), each (R, M).

    Returns:
        mask (B, K, M) bool (False outside the core rows and outside the map),
        noise (B, K, M) float64 training-cell mean (NaN where undecided).
    """
    b, k, m = power.shape
    h = int(half_rows)
    if k < 2 * h + 1:
        raise ValueError(f"cfar_on_patches: patches of {k} rows cannot hold a CFAR range window "
                         f"of 2 * {h} + 1 rows")
    first = np.asarray(first_row, dtype=np.int64).reshape(b)
    mask = np.zeros((b, k, m), dtype=bool)
    noise = np.full((b, k, m), np.nan)
    inside = (first >= 0) & (first + k <= n_rows_total)
    idx = np.flatnonzero(inside)
    if idx.size:
        msk, _, nse = run_cfar(power[idx].reshape(-1, m))
        mask[idx] = np.asarray(msk).reshape(-1, k, m)
        noise[idx] = np.asarray(nse).reshape(-1, k, m)
    # rare: the pedestrian within a CFAR window of a map edge (frames whose core rows all lie
    # outside the map cannot detect anything and are skipped)
    core_inside = (first + h < n_rows_total) & (first + k - h > 0)
    for i in np.flatnonzero(~inside & core_inside):
        lo, hi = max(0, -first[i]), min(k, n_rows_total - first[i])
        msk, _, nse = run_cfar(power[i, lo:hi])
        mask[i, lo:hi], noise[i, lo:hi] = msk, nse
    mask[:, :h] = False
    mask[:, k - h:] = False
    noise[:, :h] = np.nan
    noise[:, k - h:] = np.nan
    return mask, noise


# ------------------------------------------------------------------ reduced chain: one batch
@dataclass(frozen=True)
class _ReducedSetup:
    """What every batch of the reduced chain needs, computed once."""

    chain: object
    range_window: np.ndarray
    doppler_window: np.ndarray
    cell_noise_power: float       # per range-Doppler cell and channel, cube units^2
    sample_noise_power: float     # per ADC sample, cube units^2
    output_scale: float
    half_rows: int
    core_half_rows: int
    block_chol: np.ndarray        # Cholesky factor of the snapshot block's noise covariance
    range_chol: np.ndarray        # the same for a cell and its two range neighbours (3 x 3)
    ula_flat: np.ndarray          # ULA element -> flat virtual channel (tx * n_rx + rx)


def _reduced_setup(chain, core_half_rows: int, adc_headroom_db: float) -> _ReducedSetup:
    from blindspot.dsp.range_doppler import window
    from blindspot.radar.rd_patch import block_noise_covariance, post_fft_noise_power
    from blindspot.radar.simulator import FmcwSimulator

    radar, det = chain.radar, chain.detect
    if det.snapshots != "cells":
        raise ValueError(f"detect.snapshots = {det.snapshots!r}: the reduced chain builds the "
                         "'cells' snapshots only; use full_chain=True for 'chirps'")
    scale = FmcwSimulator(radar, chain.array, noise=False,
                          adc_headroom_db=adc_headroom_db).output_scale
    wr = window(det.range_window, radar.n_samples)
    wd = window(det.doppler_window, radar.n_chirps)
    sample_noise = radar.noise_power_w * scale**2
    hr, hd = det.cell_half
    cov = block_noise_covariance(wr, wd, 2 * hr + 1, 2 * hd + 1)
    chol = np.linalg.cholesky(cov + 1e-12 * cov[0, 0].real * np.eye(cov.shape[0]))
    cov3 = block_noise_covariance(wr, wd, 3, 1)
    chol3 = np.linalg.cholesky(cov3 + 1e-12 * cov3[0, 0].real * np.eye(3))
    t, r = chain.array.ula_index
    return _ReducedSetup(chain=chain, range_window=wr, doppler_window=wd,
                         cell_noise_power=post_fft_noise_power(sample_noise, wr, wd),
                         sample_noise_power=sample_noise, output_scale=scale,
                         half_rows=int(chain.cfar.guard[0] + chain.cfar.train[0]),
                         core_half_rows=int(core_half_rows), block_chol=chol, range_chol=chol3,
                         ula_flat=np.asarray(t) * radar.n_rx + np.asarray(r))


_FRAME_FIELDS = ("x_m", "y_m", "range_m", "angle_deg", "velocity_mps", "snr_db", "n_detections")


def _empty_frames(n: int) -> dict[str, np.ndarray]:
    out = {k: np.full(n, np.nan) for k in _FRAME_FIELDS}
    out["n_detections"] = np.zeros(n, dtype=np.int64)
    return out


@dataclass
class _ReducedDetections:
    """Steps 1-2 of the reduced chain on B frames: the patches' terms and the CFAR detections
    (frame b, patch row k, Doppler bin d, power, SNR), in the chain's per-frame order (moving
    first, then strongest, by the chain's own ``order_detections``)."""

    first: np.ndarray
    r_t: np.ndarray
    d_t: np.ndarray
    c_all: np.ndarray
    bi: np.ndarray
    ki: np.ndarray
    di: np.ndarray
    pw: np.ndarray
    snr_db: np.ndarray
    moving: np.ndarray
    power: np.ndarray             # (B, K, M) the patches' detection map (sub-bin range reads it)


def _reduced_detections(setup: _ReducedSetup, sc: PointScatterers,
                        rng: np.random.Generator) -> _ReducedDetections:
    """Range-Doppler patches of B frames (exact signal energy + one noise draw per cell), the
    chain's CFAR on them as on the full map, range window, local maxima, detection order."""
    from blindspot.radar.rd_patch import patch_terms, separable_channel_energy

    chain = setup.chain
    radar, det = chain.radar, chain.detect
    n_rows = chain.range_axis_m.size
    h, core = setup.half_rows, setup.core_half_rows
    k = 2 * (core + h) + 1
    centre = np.rint(np.mean(sc.range_m, axis=1) / radar.range_bin_m).astype(np.int64)
    first = centre - core - h
    # 1. range-Doppler patch terms, detection map (exact signal energy + noise draw)
    r_t, d_t, c_all = patch_terms(sc, radar, chain.array, first, k, setup.range_window,
                                  setup.doppler_window, "all")
    energy = separable_channel_energy(r_t, d_t, c_all)
    power = noncoherent_power(rng, energy, radar.n_tx * radar.n_rx, setup.cell_noise_power)
    # 2. the chain's CFAR (on the patches as on the full map), range window, local maxima
    rows = first[:, None] + np.arange(k)
    exists = (rows >= 0) & (rows < n_rows)
    mask, noise = cfar_on_patches(power, first, n_rows, h, chain.run_cfar)
    ok_rows = exists & chain.range_ok[np.clip(rows, 0, n_rows - 1)]
    mask &= ok_rows[..., None]
    if det.peak_only:
        mask &= local_maxima(power, exists)
    bi, ki, di = np.nonzero(mask)
    pw = power[bi, ki, di]
    order, mov = chain.order_detections(bi, pw, di)   # per frame: moving first, then strongest
    bi, ki, di, pw = bi[order], ki[order], di[order], pw[order]
    snr_db = 10.0 * np.log10(pw / noise[bi, ki, di])
    return _ReducedDetections(first, r_t, d_t, c_all, bi, ki, di, pw, snr_db, mov, power)


def _reduced_snapshots(setup: _ReducedSetup, red: _ReducedDetections, sel: np.ndarray,
                       rng: np.random.Generator) -> np.ndarray:
    """(len(sel), n_ula, L) cell snapshots of the detections ``sel`` on the ULA elements:
    the exact signal of every scatterer in the 3 x 3 neighbourhood plus noise correlated across
    cells as the windowed FFTs correlate it."""
    chain = setup.chain
    det = chain.detect
    n_rows = chain.range_axis_m.size
    m = chain.radar.n_chirps
    hr, hd = det.cell_half
    dr, dd = np.meshgrid(np.arange(-hr, hr + 1), np.arange(-hd, hd + 1), indexing="ij")
    dr, dd = dr.ravel(), dd.ravel()
    b_s, k_s, d_s = red.bi[sel], red.ki[sel], red.di[sel]
    first = red.first
    g_rows = np.clip(first[b_s, None] + k_s[:, None] + dr, 0, n_rows - 1)   # as the chain
    kk = g_rows - first[b_s, None]                                        # (D, L) patch row
    dop = (d_s[:, None] + dd) % m                                         # (D, L)
    coef = (np.take_along_axis(red.r_t[b_s], kk[:, None, :], axis=2)
            * np.take_along_axis(red.d_t[b_s], dop[:, None, :], axis=2))  # (D, S, L)
    c_ula = red.c_all[b_s][:, :, setup.ula_flat]                          # (D, S, E)
    x = c_ula.transpose(0, 2, 1) @ coef                                   # (D, E, L)
    n_el, n_l = x.shape[1], dr.size
    z = rng.standard_normal((sel.size, n_el, n_l, 2)).view(np.complex128)[..., 0]
    z *= np.sqrt(setup.sample_noise_power / 2.0)
    blk = z @ setup.block_chol.T                  # cells correlated as the FFTs make them
    # a clipped neighbour repeats its row's noise, exactly as the chain repeats the cell
    cell = (kk - k_s[:, None] + hr) * (2 * hd + 1) + (dd + hd)
    return x + np.take_along_axis(blk, cell[:, None, :], axis=2)


def _measure_batch_reduced(setup: _ReducedSetup, sc: PointScatterers,
                           rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Measured point of each of B frames through the reduced chain (see measure_paths): the
    patches are synthesised here, every detection step is the chain's own."""
    chain = setup.chain
    det = chain.detect
    b = sc.shape[0]
    n_rows = chain.range_axis_m.size
    red = _reduced_detections(setup, sc, rng)
    bi, ki, di = red.bi, red.ki, red.di
    vel = chain.velocity_axis_mps[di]
    # 3. angles of the moving detections within each frame's DOA budget (static ones cannot
    # become the pedestrian's point, so their angles are not needed)
    sel = np.flatnonzero(chain.doa_budget(bi) & red.moving)
    angle = np.full(bi.size, np.nan)
    if sel.size:
        x = _reduced_snapshots(setup, red, sel, rng)
        angle[sel] = chain.angles(x, di[sel])
    # 4. the pedestrian's point per frame (the chain's grouping)
    # the chain's range of each detection (sub-bin with range_interpolation: ipdft), from the
    # full map's bin numbers; the pedestrian's candidates (``sel``) read their range neighbours
    # from a fresh draw of the three cells with the noise correlation the range window gives
    # them (-2/3 for Hann), since the map's cells were drawn independently
    rows_full = np.clip(red.first[bi] + ki, 0, n_rows - 1)
    range_m = chain.detection_range(red.power, bi, ki, di, rows_full)
    if sel.size and chain.range_table is not None:
        trio = _range_trio_power(setup, red.r_t, red.d_t, red.c_all, bi[sel], ki[sel], di[sel],
                                 rng)
        range_m[sel] = chain.detection_range(trio, np.arange(sel.size),
                                             np.ones(sel.size, dtype=np.int64), di[sel],
                                             rows_full[sel], column=np.zeros(sel.size, np.int64))
    pts = group_points(bi, range_m, vel, angle, red.snr_db, det.min_speed_mps, det.cluster_gap_m,
                       estimator=det.point_estimator)
    out = _empty_frames(b)
    for key in _FRAME_FIELDS:
        out[key][pts["frame"]] = pts[key]
    return out


def _take_frames(sc: PointScatterers, keep: np.ndarray) -> PointScatterers:
    """The scatterers of frames ``keep`` (indices into the B axis)."""
    return PointScatterers(range_m=sc.range_m[keep], velocity_mps=sc.velocity_mps[keep],
                           azimuth_rad=sc.azimuth_rad[keep], amplitude=sc.amplitude[keep],
                           elevation_rad=sc.elevation_rad[keep])


def _range_trio_power(setup: _ReducedSetup, r_t: np.ndarray, d_t: np.ndarray, c_all: np.ndarray,
                      b: np.ndarray, k: np.ndarray, d: np.ndarray, rng: np.random.Generator
                      ) -> np.ndarray:
    """Detection-map values of cells (b, k - 1..k + 1, d) (D,) over every channel: exact signal
    (the patch terms) plus channel noise correlated across the three range bins as the
    windowed FFTs correlate it. Returns (D, 3, 1) maps (rows = the three range bins)."""
    rows = k[:, None] + np.arange(-1, 2)                                         # (D, 3)
    rows = np.clip(rows, 0, r_t.shape[2] - 1)
    coef = (np.take_along_axis(r_t[b], rows[:, None, :], axis=2)
            * d_t[b][np.arange(b.size), :, d][:, :, None])                      # (D, S, 3)
    sig = np.einsum("dsj,dsc->djc", coef, c_all[b])                             # (D, 3, C)
    z = rng.standard_normal(sig.shape[:1] + sig.shape[2:] + (3, 2)).view(np.complex128)[..., 0]
    z *= np.sqrt(setup.sample_noise_power / 2.0)
    noise = (z @ setup.range_chol.T).transpose(0, 2, 1)                         # (D, 3, C)
    x = sig + noise
    return (x.real ** 2 + x.imag ** 2).sum(axis=-1)[..., None]


def _measure_batch_full(chain, simulator, pos: np.ndarray, vel: np.ndarray, rcs: np.ndarray,
                        seed: int, frame_ids: np.ndarray) -> dict[str, np.ndarray]:
    """Measured point of each frame through the simulator's cube and DetectionChain.process."""
    from blindspot.radar.simulator import frame_bit_generator

    out = _empty_frames(pos.shape[0])
    cube = np.empty(simulator.shape, dtype=np.complex64)
    for i in range(pos.shape[0]):  # one 64 x 12 x 16 x 256 cube per frame: the reference path
        simulator.frame(pos[i], vel[i], rcs, out=cube,
                        bit_generator=frame_bit_generator(seed, int(frame_ids[i])))
        res = chain.process(cube, keep_spectrum=False)
        if len(res.point):
            row = res.point.iloc[0]
            for key in _FRAME_FIELDS:
                out[key][i] = row[key]
    return out


# ------------------------------------------------------------------------------ public API
@dataclass(frozen=True)
class PathMeasurement:
    """Measured paths and per-point diagnostics; all arrays (P, T) or (P, T, 2).

    Attributes:
        xy: measured points (x, y), m; NaN rows where the chain gave no point.
        range_m, angle_deg, velocity_mps: the point's range, angle and SNR-weighted radial
            velocity (NaN where no point).
        snr_db: strongest SNR among the pedestrian's detections (NaN where no point).
        n_detections: detections grouped into the point (0 where no point).
    """

    xy: np.ndarray
    range_m: np.ndarray
    angle_deg: np.ndarray
    velocity_mps: np.ndarray
    snr_db: np.ndarray
    n_detections: np.ndarray

    @property
    def detected(self) -> np.ndarray:
        """(P, T) True where the chain produced a point."""
        return np.isfinite(self.xy[..., 0])


def measure_paths(truth_paths: np.ndarray, radar: RadarConfig, array=None, cfar_cfg=None,
                  doa_cfg=None, detect_cfg=None, *, pedestrian: PedestrianModel, seed: int = 0,
                  paths_per_batch: int = 8, core_half_rows: int = 8, full_chain: bool = False,
                  adc_headroom_db: float = 60.0, occluders: np.ndarray | None = None,
                  occlusion_db: float = 50.0, frames: np.ndarray | None = None,
                  progress: bool = True) -> PathMeasurement:
    """Every point of every truth path through the radar chain.

    Args:
        truth_paths: (P, T, 2) clean body-centre paths at the radar's frame period, m.
        radar: the chirp profile (``conf/radar``); ``array`` its virtual array (default from
            the profile).
        cfar_cfg, doa_cfg, detect_cfg: the ``cfar`` / ``doa`` / ``detect`` config groups
            (mappings or the chain's dataclasses), exactly as for
            :meth:`DetectionChain.from_config`.
        pedestrian: the walking body (:meth:`PedestrianModel.from_scene`).
        seed: drives the gait phase of each path and all receiver noise.
        paths_per_batch: paths processed together (part of the random stream: the same seed and
            ``paths_per_batch`` give identical bytes).
        core_half_rows: reduced chain only: detections are looked for within this many range
            bins of the pedestrian (the patch adds the CFAR window on both sides).
        full_chain: simulate every 64 x 12 x 16 x 256 cube and run ``DetectionChain.process``
            (the reference; a few frames/s) instead of the reduced chain.
        adc_headroom_db: the simulator's ADC full scale above the noise (sets the cube units
            when ``radar.adc_bits`` is set, as the dB-domain CFAR needs).
        occluders: (P, E, 2) footprint of an occluding object per path (a parked car,
            :func:`blindspot.radar.scene.car_footprint`), or None. A body part whose line of
            sight crosses its path's footprint loses ``occlusion_db`` of received power, as
            ``Scene.scatterers_at`` applies it (amplitude times ``10 ** (-dB / 20)``; a hard
            shadow, no diffraction; the car's own static returns are not added: at zero Doppler
            they fall below ``detect.min_speed_mps`` and are never the pedestrian's point).
            Reduced chain only.
        occlusion_db: that loss, dB >= 0.
        frames: (P, T) bool, the frames to measure (the others are returned as missed, NaN,
            and cost nothing); None = all. Reduced chain only.
        progress: show a progress bar.

    Returns:
        :class:`PathMeasurement` with NaN where no point was produced (never an invented one).

    The reduced chain (default) is exact in: the signal of every scatterer in every patch cell
    and channel (the analytic patch equals the FFT of the simulated cube), the marginal
    distribution of every detection-map cell (non-central chi-square of 2 x 192 degrees of
    freedom), CFAR (the chain's own ``run_cfar`` on patches wide enough for the training
    window), the local-maximum rule, detection order and budget, snapshots (the 3 x 3
    neighbourhood on the 86 ULA elements with noise correlated across cells as the windowed
    FFTs correlate it), TDM compensation, MUSIC (same estimate) and grouping (the chain's
    ``group_point``). Approximations: (1) the detection map's noise is independent between
    cells (the FFT correlates neighbours; with 192 channels summed the cell-to-cell fluctuation
    it affects is +-7 % of the mean); the sub-bin range of the pedestrian's candidates, which
    reads a cell's two range neighbours, uses a fresh draw of those three cells over all
    channels with the window's correlation (-2/3 between Hann neighbours) instead; (2) the snapshot noise is drawn afresh, not conditioned on
    the map value that made the cell a detection; (3) only cells within ``core_half_rows`` range
    bins of the pedestrian are searched, so false alarms elsewhere in the map (expected count
    n_cells x Pfa per frame, ~0 for the paper's dB-domain CFAR) are not produced; (4) no ADC
    rounding (16-bit codes put the noise at ~33 LSB, so rounding adds < 0.01 % noise power).
    """
    from tqdm.auto import tqdm

    from blindspot.dsp.chain import DetectionChain
    from blindspot.radar.array import array_for

    xy = np.asarray(truth_paths, dtype=np.float64)
    vel, turn, dist = path_kinematics(xy, radar.frame_period_s)
    p_count, t_count = xy.shape[:2]
    if array is None:
        array = array_for(radar)
    chain = DetectionChain.from_config(radar, array, cfar_cfg, doa_cfg, detect_cfg)
    if not (isinstance(paths_per_batch, (int, np.integer)) and paths_per_batch >= 1):
        raise ValueError(f"paths_per_batch: expected a positive integer, found {paths_per_batch!r}")
    if not (isinstance(core_half_rows, (int, np.integer)) and core_half_rows >= 1):
        raise ValueError(f"core_half_rows: expected a positive integer, found {core_half_rows!r}")
    if occluders is not None:
        occluders = np.asarray(occluders, dtype=np.float64)
        if occluders.ndim != 3 or occluders.shape[0] != p_count or occluders.shape[2] != 2:
            raise ValueError(f"occluders: expected footprints of shape (P, E, 2) with P = "
                             f"{p_count}, found shape {occluders.shape}")
        if not (np.isfinite(occlusion_db) and occlusion_db >= 0):
            raise ValueError(f"occlusion_db: expected a finite loss >= 0 dB, found {occlusion_db!r}")
        if full_chain:
            raise ValueError("occluders: only the reduced chain applies the per-part loss; "
                             "use full_chain=False")
        from blindspot.radar.occlusion import segment_crosses_polygons
    if frames is not None:
        frames = np.asarray(frames)
        if frames.shape != (p_count, t_count) or frames.dtype != bool:
            raise ValueError(f"frames: expected a boolean mask of shape (P, T) = "
                             f"{(p_count, t_count)}, found {frames.dtype} {frames.shape}")
        if full_chain:
            raise ValueError("frames: only the reduced chain measures a subset of frames; "
                             "use full_chain=False")
    # the gait phase offset of each path (drawn for all paths at once: batch-independent)
    gait0 = np.random.default_rng(np.random.SeedSequence([seed, 1])).uniform(0, 2 * np.pi, p_count)
    gait = gait0[:, None] + 2.0 * np.pi * dist / pedestrian.stride_length_m
    fields = {k: np.full((p_count, t_count), np.nan) for k in _FRAME_FIELDS}
    fields["n_detections"] = np.zeros((p_count, t_count), dtype=np.int64)
    if full_chain:
        from blindspot.radar.simulator import FmcwSimulator

        simulator = FmcwSimulator(radar, array, noise=True, adc_headroom_db=adc_headroom_db)
    else:
        setup = _reduced_setup(chain, core_half_rows, adc_headroom_db)
    starts = range(0, p_count, paths_per_batch)
    with tqdm(total=p_count * t_count, desc="paths through the radar", unit="frame",
              disable=not progress) as bar:
        for batch, lo in enumerate(starts):
            hi = min(lo + paths_per_batch, p_count)
            pos, v3 = body_scatterers(xy[lo:hi].reshape(-1, 2), vel[lo:hi].reshape(-1, 2),
                                      turn[lo:hi].reshape(-1), gait[lo:hi].reshape(-1), pedestrian)
            if full_chain:
                ids = (np.arange(lo, hi)[:, None] * t_count + np.arange(t_count)).reshape(-1)
                res = _measure_batch_full(chain, simulator, pos, v3, pedestrian.rcs_m2, seed, ids)
            else:
                sc = point_scatterers(pos, v3, pedestrian.rcs_m2, radar,
                                      output_scale=setup.output_scale)
                if occluders is not None:
                    parts_xy = pos[..., :2].reshape(hi - lo, -1, 2)       # (paths, T * parts, 2)
                    hidden = segment_crosses_polygons(parts_xy, occluders[lo:hi])
                    gain = np.where(hidden, 10.0 ** (-occlusion_db / 20.0), 1.0)
                    sc = replace(sc, amplitude=sc.amplitude * gain.reshape(sc.amplitude.shape))
                rng = np.random.default_rng(np.random.SeedSequence([seed, 2, batch]))
                if frames is None:
                    res = _measure_batch_reduced(setup, sc, rng)
                else:
                    keep = np.flatnonzero(frames[lo:hi].reshape(-1))
                    res = _empty_frames(sc.range_m.shape[0])
                    if keep.size:
                        sub = _measure_batch_reduced(setup, _take_frames(sc, keep), rng)
                        for key in _FRAME_FIELDS:
                            res[key][keep] = sub[key]
            for key in _FRAME_FIELDS:
                fields[key][lo:hi] = res[key].reshape(hi - lo, t_count)
            bar.update((hi - lo) * t_count)
    return PathMeasurement(xy=np.stack([fields["x_m"], fields["y_m"]], axis=-1),
                           range_m=fields["range_m"], angle_deg=fields["angle_deg"],
                           velocity_mps=fields["velocity_mps"], snr_db=fields["snr_db"],
                           n_detections=fields["n_detections"])


def error_statistics(measured: PathMeasurement, truth_paths: np.ndarray) -> dict[str, float]:
    """Point-error statistics of measured paths against their truth (P, T, 2):
    detection_rate (share of frames with a point), median_error_m and p90_error_m (Euclidean,
    detected points), range_error_std_m and angle_error_std_deg (measured minus truth range and
    bearing of the body centre), mean_detections (per detected point)."""
    truth = np.asarray(truth_paths, dtype=np.float64)
    det = measured.detected
    err = np.linalg.norm(measured.xy - truth, axis=-1)[det]
    r_true = np.hypot(truth[..., 0], truth[..., 1])[det]
    a_true = np.degrees(np.arctan2(truth[..., 0], truth[..., 1]))[det]
    r_meas = np.hypot(measured.xy[..., 0], measured.xy[..., 1])[det]
    a_meas = np.degrees(np.arctan2(measured.xy[..., 0], measured.xy[..., 1]))[det]
    nan = float("nan")
    return {
        "n_frames": int(det.size),
        "detection_rate": float(det.mean()) if det.size else nan,
        "median_error_m": float(np.median(err)) if err.size else nan,
        "p90_error_m": float(np.percentile(err, 90)) if err.size else nan,
        "range_error_std_m": float(np.std(r_meas - r_true)) if err.size else nan,
        "angle_error_std_deg": float(np.std(a_meas - a_true)) if err.size else nan,
        "mean_detections": float(measured.n_detections[det].mean()) if err.size else nan,
    }
