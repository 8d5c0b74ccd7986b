"""Pass synthetic pedestrian paths through the radar chain, point by point (paper section III).

Every truth point of a path becomes a walking pedestrian (the scene model's body: torso, head,
swinging arms and legs, from :mod:`blindspot.radar.scene`) seen by the FMCW radar in one frame;
the frame goes through range FFT, Doppler FFT, CA-CFAR, Doppler compensation, MUSIC and the
points step, and what comes out is the *measured* point: quantised to the 0.5 m range bins,
with the angle error of MUSIC on a real body, or missing (NaN) when CFAR found nothing. This is
the measurement error the LSTM has to learn to live with.

Two ways to get there
---------------------
* ``full_chain=True``: the project's simulator (:class:`~blindspot.radar.simulator.FmcwSimulator`)
  builds each 64 x 12 x 16 x 256 cube and :class:`~blindspot.dsp.chain.DetectionChain` processes
  it. Exact, and about 15 frames/s: the reference.
* default, the *reduced* chain: the same scatterers give a range-Doppler *patch* around the
  pedestrian computed analytically (:mod:`blindspot.radar.rd_patch`: windowed DTFT at the bin
  frequencies, identical to the FFT of the simulated cube), with noise drawn with the FFT's exact
  statistics, and the chain's own functions (``ca_cfar_2d``, Doppler compensation,
  ``music_angles``, points) run on the patch for thousands of frames at once. See
  :func:`measure_paths` for what is exact and what is approximated; the test
  ``tests/dsp/test_path_measurement.py`` shows the point-error statistics of both agree within
  10 %.

Geometry and units follow the project: radar at the origin, boresight +y, x to the right, SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig
from blindspot.radar.radar_equation import received_power_w
from blindspot.radar.rd_patch import PointScatterers
from blindspot.radar.scene import BodyPart, SceneConfig

__all__ = [
    "PedestrianModel",
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
            raise ValueError(f"PedestrianModel.stride_length_m: expected > 0, found {self.stride_length_m}")

    @classmethod
    def from_scene(cls, scene: SceneConfig) -> PedestrianModel:
        """The body of a scene configuration (e.g. one of ``load_scenes(conf/scene/paper.yaml)``)."""
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
                    guard, train, **rule) -> tuple[np.ndarray, np.ndarray]:
    """Run the chain's 2-D CFAR (:func:`blindspot.dsp.cfar.cfar_2d`) on a batch of patches.

    Each frame's patch holds rows ``first_row[b] .. first_row[b] + K - 1`` of a map of
    ``n_rows_total`` range bins and *all* Doppler bins (so Doppler wraps as in the full map).
    Only the core rows ``[h, K - h)``, ``h = guard_range + train_range``, are decided: their
    training windows lie inside the patch, so the result equals CFAR on the full map. Frames
    whose patches lie inside the map are stacked along range and processed in one call (rows of
    neighbouring frames only ever fall into the windows of the undecided border rows); frames
    whose patch crosses the first or last range bin are processed one by one on their existing
    rows, so the edge rule (fewer training cells, larger factor) is the full map's.

    Args:
        power: (B, K, M) detection-map patches.
        first_row: (B,) map row of each patch's first row (may be < 0 or run past the end).
        n_rows_total: number of range bins of the full map.
        guard, train: CFAR half-widths (range, Doppler), as for ``ca_cfar_2d``.
        **rule: pfa / scale / domain / mode / n_looks, passed on unchanged.

    Returns:
        mask (B, K, M) bool (False outside the core rows and outside the map),
        noise (B, K, M) float64 training-cell mean (NaN where undecided).
    """
    from blindspot.dsp.cfar import cfar_2d

    b, k, m = power.shape
    g = np.broadcast_to(np.asarray(guard), (2,))
    t = np.broadcast_to(np.asarray(train), (2,))
    h = int(g[0] + t[0])
    if k < 2 * h + 1:
        raise ValueError(f"cfar_on_patches: patches of {k} rows cannot hold a CFAR range window "
                         f"of 2*(guard+train)+1 = {2 * h + 1} rows")
    first = np.asarray(first_row, dtype=np.int64).reshape(b)
    mask = np.zeros((b, k, m), dtype=bool)
    noise = np.full((b, k, m), np.nan)
    inside = (first >= 0) & (first + k <= n_rows_total)
    idx = np.flatnonzero(inside)
    if idx.size:
        res = cfar_2d(power[idx].reshape(-1, m), guard, train, **rule)
        mask[idx] = res.mask.reshape(-1, k, m)
        noise[idx] = res.noise.reshape(-1, k, m)
    for i in np.flatnonzero(~inside):  # rare: pedestrian within a CFAR window of the map edge
        lo, hi = max(0, -first[i]), min(k, n_rows_total - first[i])
        res = cfar_2d(power[i, lo:hi], guard, train, **rule)
        mask[i, lo:hi], noise[i, lo:hi] = res.mask, res.noise
    mask[:, :h] = False
    mask[:, k - h:] = False
    noise[:, :h] = np.nan
    noise[:, k - h:] = np.nan
    return mask, noise


# ------------------------------------------------------------------ reduced chain: angles
def music_peak_angles(snapshots: np.ndarray, positions: np.ndarray, n_signals: int = 3,
                      grid_deg: np.ndarray | None = None, *, forward_backward: bool = False,
                      newton_steps: int = 6) -> np.ndarray:
    """The strongest MUSIC peak per detection, for tens of thousands of detections at once.

    The same estimate as :func:`blindspot.dsp.doa.music_angles` with ``n_targets=1`` (the test
    checks equality): signal subspace = the ``n_signals`` principal eigenvectors of
    ``R = X X^H / L`` (forward-backward: of ``(R + J conj(R) J) / 2``), maximum of
    ``g(u) = |E_s^H a(u)|^2`` on the grid, refined by Newton steps on ``u = sin theta`` kept
    between the neighbouring grid points. Faster for large batches in two ways: when there are
    fewer (augmented) snapshots than elements the principal eigenvectors come from the small
    L x L Gram matrix ``X^H X`` (``E_s = X V / sqrt(w)``, the same subspace), and the batched
    products and ``eigh`` run in torch, whose batched small-matrix kernels are several times
    faster than numpy's here.

    snapshots: complex (D, M, L); positions: (M,) wavelengths -> (D,) degrees (NaN if D rows
    have no signal at all).
    """
    import torch

    from blindspot.dsp.doa import DEFAULT_GRID_DEG, steering_matrix

    grid = DEFAULT_GRID_DEG if grid_deg is None else np.asarray(grid_deg, dtype=np.float64)
    x = np.asarray(snapshots)
    p = np.asarray(positions, dtype=np.float64)
    if x.ndim != 3 or x.shape[1] != p.size:
        raise ValueError(f"music_peak_angles: expected snapshots (D, M={p.size}, L), found {x.shape}")
    d, m, _ = x.shape
    if d == 0:
        return np.zeros(0)
    y = torch.from_numpy(np.ascontiguousarray(x, dtype=np.complex128))
    if forward_backward:
        y = torch.cat([y, torch.flip(y.conj(), dims=(1,))], dim=2)
    lp = y.shape[2]
    if lp < m:
        gram = y.conj().transpose(1, 2) @ y                       # (D, L', L')
        w, v = torch.linalg.eigh(gram)
        w, v = w[:, lp - n_signals:], v[:, :, lp - n_signals:]
        e = (y @ v) / torch.sqrt(torch.clamp(w, min=1e-300))[:, None, :]
    else:
        r = y @ y.conj().transpose(1, 2)
        _, v = torch.linalg.eigh(r)
        e = v[:, :, m - n_signals:]
    e = e.numpy()                                                   # (D, M, ns)
    a = steering_matrix(p, grid)                                    # (M, G)
    z = e.conj().transpose(0, 2, 1).reshape(-1, m) @ a              # (D*ns, G)
    g = (z.real**2 + z.imag**2).reshape(d, -1, grid.size).sum(axis=1)
    idx = np.argmax(g, axis=1)
    u_grid = np.sin(np.radians(grid))
    lo = u_grid[np.maximum(idx - 1, 0)]
    hi = u_grid[np.minimum(idx + 1, grid.size - 1)]
    u = u_grid[idx]
    k = 2j * np.pi * p
    eh = e.conj().transpose(0, 2, 1)                                # (D, ns, M)
    for _ in range(newton_steps):                                   # batched Newton on g(u)
        av = np.exp(k[None, :] * u[:, None])                        # (D, M)
        z0 = np.einsum("drm,dm->dr", eh, av)
        z1 = np.einsum("drm,dm->dr", eh, av * k)
        z2 = np.einsum("drm,dm->dr", eh, av * k * k)
        g1 = 2 * np.sum(z0.conj() * z1, axis=1).real
        g2 = 2 * (np.sum(np.abs(z1) ** 2, axis=1) + np.sum(z0.conj() * z2, axis=1).real)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(g2 < 0, -g1 / g2, 0.0)
        u = np.clip(u + step, lo, hi)
    return np.degrees(np.arcsin(np.clip(u, -1.0, 1.0)))
