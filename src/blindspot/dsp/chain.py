"""The detection chain of one radar: cube -> range-Doppler map -> CFAR -> MUSIC -> points.

Configured once (``DetectionChain.from_config(radar, array, cfg_cfar, cfg_doa, cfg_detect)``,
the three ``cfg_*`` being the Hydra groups ``cfar``, ``doa`` and ``detect``), then
``process(cube)`` per frame:

1. ``range_doppler``: windowed range and Doppler FFTs (zero-Doppler centred), in place.
2. ``map``: detection map = sum of |X|^2 over all virtual channels (range, doppler).
3. ``cfar``: 2-D CFAR (CA / GO / SO / OS) on the map; optionally only local maxima (3 x 3,
   Doppler wrapped) of the map are kept, so one target gives one detection per peak.
4. ``detections``: table of detections in the range window (``min_range_m``..``max_range_m``),
   SNR = power / mean of the CFAR training cells (local noise-plus-interference: next to the
   parked car's returns it is lower than the SNR over thermal noise).
5. ``doa``: for the ``max_detections`` strongest detections, moving ones first: snapshots
   (``snapshots.py``), TDM-MIMO Doppler compensation with each detection's Doppler bin, ULA
   elements, batched MUSIC (or Bartlett / Capon); angle of the strongest peak. Others keep NaN.
6. ``points``: static clutter removed by speed, the pedestrian's detections grouped into one
   SNR-weighted point (``points.py``), or no point.

``process`` returns a :class:`FrameResult` with the maps for figures and per-step timings;
``process_many`` runs a whole :class:`~blindspot.radar.source.FrameSource` with a progress bar
and returns the detections and points of every frame (no maps kept).
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from blindspot.dsp.cfar import cfar_2d, os_cfar_2d, training_mean
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.dsp.doa import doa_angles
from blindspot.dsp.doppler_compensation import compensate_tdm
from blindspot.dsp.points import (
    DETECTION_COLUMNS, POINT_COLUMNS, frame_points, group_point, moving,
)
from blindspot.dsp.range_doppler import RangeDoppler, detection_map
from blindspot.dsp.snapshots import cell_snapshots, chirp_snapshots
from blindspot.radar.array import VirtualArray
from blindspot.radar.config import ConfigError, RadarConfig

# ---------------------------------------------------------------------------------------------
# results


@dataclass
class FrameResult:
    """One processed frame.

    detections : DataFrame ``DETECTION_COLUMNS`` (+ moving, doa) of this frame
    point      : DataFrame with 0 or 1 row (``points.POINT_COLUMNS``)
    power, threshold, noise : (range, doppler) float64 maps; mask : (range, doppler) CFAR cells
    spectrum   : (G,) pseudo-spectrum of the strongest moving detection (None without one)
    spectrum_detection : its row index in ``detections``
    """

    frame: int
    time_s: float
    detections: pd.DataFrame
    point: pd.DataFrame
    power: np.ndarray
    threshold: np.ndarray
    mask: np.ndarray
    noise: np.ndarray
    spectrum: np.ndarray | None
    spectrum_detection: int | None
    angles_deg: np.ndarray
    range_axis_m: np.ndarray
    velocity_axis_mps: np.ndarray
    timings_ms: dict[str, float] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------
# the chain


class DetectionChain:
    """Range-Doppler, CFAR, angle and point extraction for one radar profile and array."""

    def __init__(self, radar: RadarConfig, array: VirtualArray, cfar: CfarConfig,
                 doa: DoaConfig, detect: DetectConfig):
        if array.n_tx != radar.n_tx or array.n_rx != radar.n_rx:
            raise ConfigError("radar.array", radar.array,
                              f"an array with n_tx={radar.n_tx}, n_rx={radar.n_rx} "
                              f"(got {array.n_tx} x {array.n_rx})")
        self.radar, self.array, self.cfar, self.doa, self.detect = radar, array, cfar, doa, detect
        full_axis = radar.range_axis_m()
        n_range = None
        if detect.max_range_m is not None:
            n_range = int(np.searchsorted(full_axis, detect.max_range_m, side="right"))
            if n_range < 2:
                raise ConfigError("detect.max_range_m", detect.max_range_m,
                                  f"at least two range bins ({full_axis[1]:.3g} m)")
            n_range = min(n_range, radar.n_samples)
        self.rd = RangeDoppler(radar.n_chirps, radar.n_samples, detect.range_window,
                               detect.doppler_window, detect.workers, n_range)
        self.range_axis_m = full_axis[:n_range]
        self.velocity_axis_mps = radar.velocity_axis_mps()
        self.grid_deg = doa.grid()
        self.slot_times_s = radar.tx_slot_times_s()
        self.ula_tx, self.ula_rx = array.ula_index
        self.ula_pos = array.ula_positions_wl
        if doa.subarray is not None and doa.subarray > self.ula_pos.size:
            raise ConfigError("doa.subarray", doa.subarray,
                              f"at most the {self.ula_pos.size} ULA elements of the array")
        m = doa.subarray or self.ula_pos.size
        if doa.method == "music" and doa.n_signals >= m:
            raise ConfigError("doa.n_signals", doa.n_signals, f"fewer than the {m} elements")
        self.n_looks = radar.n_tx * radar.n_rx if cfar.n_looks == "channels" else int(cfar.n_looks)
        r = self.range_axis_m
        hi = np.inf if detect.max_range_m is None else detect.max_range_m
        self.range_ok = (r >= detect.min_range_m) & (r <= hi)

    @classmethod
    def from_config(cls, radar: RadarConfig, array: VirtualArray, cfg_cfar: Any, cfg_doa: Any,
                    cfg_detect: Any) -> DetectionChain:
        """Build from the three Hydra groups (mappings, OmegaConf nodes or the dataclasses)."""
        cfar = cfg_cfar if isinstance(cfg_cfar, CfarConfig) else CfarConfig.from_mapping(cfg_cfar)
        doa = cfg_doa if isinstance(cfg_doa, DoaConfig) else DoaConfig.from_mapping(cfg_doa)
        det = (cfg_detect if isinstance(cfg_detect, DetectConfig)
               else DetectConfig.from_mapping(cfg_detect))
        return cls(radar, array, cfar, doa, det)

    # -------------------------------------------------------------------------------- steps
    def run_cfar(self, power: np.ndarray):
        """(mask, threshold, noise) of the configured CFAR on a (range, doppler) map."""
        c = self.cfar
        if c.domain == "db":
            floor = float(np.median(power))
            if floor <= 1.0:
                raise ConfigError(
                    "cfar.domain", "db",
                    f"a map whose noise floor is above 0 dB (found median {10 * np.log10(max(floor, 1e-300)):.1f} dB): "
                    "a dB-domain scale multiplies dB numbers, so it needs the map in ADC-code "
                    "units (radar.adc_bits set, or a real capture); otherwise use domain 'power'")
        if c.method == "os":
            mask, thr = os_cfar_2d(power, c.guard, c.train, rank=c.rank, pfa=c.pfa,
                                   scale=c.scale, domain=c.domain, n_looks=self.n_looks)
            noise, _ = training_mean(power, c.guard, c.train)
            return mask, thr, noise
        res = cfar_2d(power, c.guard, c.train, pfa=c.pfa, scale=c.scale, domain=c.domain,
                      mode=c.method, n_looks=self.n_looks)
        return res.mask, res.threshold, res.noise

    def select_cells(self, power: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(range_bin, doppler_bin) of detections: CFAR cells inside the range window, and with
        ``peak_only`` the local maxima of the map over their 3 x 3 neighbours (Doppler wraps)."""
        keep = mask & self.range_ok[:, None]
        if self.detect.peak_only:
            p = np.pad(power, ((1, 1), (0, 0)), constant_values=-np.inf)
            centre = power
            is_max = np.ones_like(keep)
            for dr in (-1, 0, 1):  # the 8 neighbours, each a whole-map comparison
                rows = p[1 + dr:1 + dr + power.shape[0]]
                for dd in (-1, 0, 1):
                    if dr == 0 and dd == 0:
                        continue
                    is_max &= centre >= np.roll(rows, -dd, axis=1)
            keep &= is_max
        return np.nonzero(keep)

    def angles(self, rd_native: np.ndarray, range_profiles: np.ndarray | None,
               range_bin: np.ndarray, doppler_bin: np.ndarray, *, spectrum_of: int | None = None
               ) -> tuple[np.ndarray, np.ndarray | None]:
        """Angles (deg) of the given detections (D,), and the pseudo-spectrum of detection
        ``spectrum_of`` (an index into them) on the scan grid."""
        if range_bin.size == 0:
            return np.zeros(0), None
        d = self.detect
        if d.snapshots == "cells":
            x = cell_snapshots(rd_native, range_bin, doppler_bin, d.cell_half)
        else:
            x = chirp_snapshots(range_profiles, range_bin)
        ula = x[:, self.ula_tx, self.ula_rx, :]  # (D, n_ula, L)
        if d.tdm_compensation:
            ula = compensate_tdm(ula, doppler_bin, self.radar.n_chirps, self.radar.loop_period_s,
                                 self.slot_times_s, self.ula_tx)
        o = self.doa
        opts = dict(forward_backward=o.forward_backward, subarray=o.subarray, loading=o.loading)
        ang, spec = doa_angles(ula, self.ula_pos, 1, o.n_signals, self.grid_deg, method=o.method,
                               return_spectrum=True, **opts)
        return ang[:, 0], (None if spectrum_of is None else spec[spectrum_of])

    # -------------------------------------------------------------------------------- frames
    def process(self, cube: np.ndarray, frame: int = 0, time_s: float = 0.0,
                keep_spectrum: bool = True) -> FrameResult:
        """Run the chain on one cube (chirps, tx, rx, samples)."""
        t = [time.perf_counter()]
        steps: dict[str, float] = {}

        def lap(name: str) -> None:
            t.append(time.perf_counter())
            steps[name] = (t[-1] - t[-2]) * 1e3

        range_profiles = None
        if self.detect.snapshots == "chirps":
            range_profiles = self.rd.range_profiles(cube)
            rd_native = self.rd.doppler(range_profiles.copy())
        else:
            rd_native = self.rd.native(cube)  # (doppler, tx, rx, range)
        lap("range_doppler")
        power = detection_map(np.moveaxis(rd_native, 3, 0))
        lap("map")
        mask, threshold, noise = self.run_cfar(power)
        lap("cfar")
        rb, db = self.select_cells(power, mask)
        pw = power[rb, db]
        vel = self.velocity_axis_mps[db]
        mov = moving(vel, self.detect.min_speed_mps)
        order = np.lexsort((-pw, ~mov))  # moving first, then strongest
        rb, db, pw, vel, mov = rb[order], db[order], pw[order], vel[order], mov[order]
        snr_db = 10 * np.log10(pw / noise[rb, db])
        lap("detections")
        n_doa = min(self.detect.max_detections, rb.size)
        spectrum_of = 0 if (keep_spectrum and n_doa and mov[0]) else None
        ang_sel, spectrum = self.angles(rd_native, range_profiles, rb[:n_doa], db[:n_doa],
                                        spectrum_of=spectrum_of)
        angles = np.full(rb.size, np.nan)
        angles[:n_doa] = ang_sel
        lap("doa")
        det = pd.DataFrame({
            "frame": np.full(rb.size, frame, dtype=np.int64),
            "range_bin": rb.astype(np.int64), "doppler_bin": db.astype(np.int64),
            "range_m": self.range_axis_m[rb], "velocity_mps": vel, "power": pw,
            "snr_db": snr_db, "angle_deg": angles, "moving": mov,
        })
        pt = group_point(self.range_axis_m[rb], vel, angles, snr_db, self.detect.min_speed_mps,
                         self.detect.cluster_gap_m)
        point = pd.DataFrame([{"frame": frame, "time_s": time_s, **pt}] if pt else [],
                             columns=list(POINT_COLUMNS))
        lap("points")
        return FrameResult(frame=frame, time_s=time_s, detections=det, point=point, power=power,
                           threshold=threshold, mask=mask, noise=noise, spectrum=spectrum,
                           spectrum_detection=spectrum_of, angles_deg=self.grid_deg,
                           range_axis_m=self.range_axis_m,
                           velocity_axis_mps=self.velocity_axis_mps, timings_ms=steps)

    def process_frames(self, frames: Iterable[np.ndarray], times_s: np.ndarray | None = None,
                       *, progress: bool = True, total: int | None = None,
                       desc: str = "detect") -> tuple[pd.DataFrame, pd.DataFrame]:
        """Detections (all frames) and points (one per frame where the pedestrian is seen) of a
        sequence of cubes; frame i gets time ``times_s[i]`` (NaN without)."""
        from tqdm.auto import tqdm

        dets = []
        for i, cube in enumerate(tqdm(frames, total=total, desc=desc, disable=not progress,
                                      unit="frame")):
            t = float(times_s[i]) if times_s is not None else float("nan")
            dets.append(self.process(cube, frame=i, time_s=t, keep_spectrum=False).detections)
        detections = (pd.concat(dets, ignore_index=True) if dets
                      else pd.DataFrame(columns=list(DETECTION_COLUMNS) + ["moving"]))
        points = frame_points(detections, times_s, self.detect.min_speed_mps,
                              self.detect.cluster_gap_m)
        return detections, points

    def process_many(self, source, *, frames: Iterable[int] | None = None,
                       progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Run a FrameSource (all frames, or the given frame indices) with a tqdm progress bar
        (``progress=False`` silences it); frame numbers and times are the source's.
        returns (detections of every frame, points: one row per frame where the pedestrian is
        seen)."""
        idx = np.arange(source.n_frames) if frames is None else np.asarray(list(frames))
        cubes = (source.frame(int(i)) for i in idx)
        det, _ = self.process_frames(cubes, None, progress=progress, total=len(idx))
        det["frame"] = idx[det["frame"].to_numpy()] if len(det) else det["frame"]
        times = np.asarray(source.times_s)
        points = frame_points(det, times, self.detect.min_speed_mps, self.detect.cluster_gap_m)
        return det, points
