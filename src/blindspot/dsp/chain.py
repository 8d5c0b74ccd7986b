"""The detection chain of one radar: cubes -> range-Doppler maps -> CFAR -> MUSIC -> points.

Configured once (``DetectionChain.from_config(radar, array, cfar, doa, detect)``, the typed
groups of :mod:`blindspot.dsp.config`), then run on a batch of frames at once; every step takes
a leading frames axis:

1. ``range_doppler``: windowed range and Doppler FFTs (zero-Doppler centred):
   cubes (frames, chirps, tx, rx, samples) -> (frames, doppler, tx, rx, range).
2. ``detection_map``: sum of |X|^2 over all virtual channels -> (frames, range, doppler).
3. ``run_cfar``: 2-D CFAR (CA / GO / SO / OS) on every map -> mask, threshold, noise
   (frames, range, doppler).
4. ``select_cells``: CFAR cells inside the range window (``min_range_m``..``max_range_m``),
   with ``peak_only`` only the local maxima of the map (:mod:`blindspot.dsp.detections`);
   ordered per frame moving first, then strongest; SNR = power / mean of the CFAR training cells
   (local noise-plus-interference: next to the parked car's returns it is lower than the SNR
   over thermal noise). ``detection_range``: with ``range_interpolation: ipdft`` each
   detection's range is refined between the bins from its two range neighbours in the map
   (:mod:`blindspot.dsp.subbin`) and corrected for the FMCW range-Doppler coupling; the
   integer ``range_bin`` stays the cell's.
5. ``angles``: for the ``max_detections`` first detections of each frame: snapshots
   (``snapshots.py``), TDM-MIMO Doppler compensation with each detection's Doppler bin, ULA
   elements, batched MUSIC (or Bartlett / Capon); the angle of its first peak (``doa.peak_order``:
   the highest, or the most powerful by least squares). Others keep NaN.
6. ``points``: static clutter removed by speed, each frame's pedestrian detections grouped into
   one point (``point_estimator``: the strongest detection, or the SNR-weighted centroid;
   :func:`blindspot.dsp.points.group_points`), or no point.

The reduced measurement of the synthesis room (:mod:`blindspot.synth.path_measurement`) runs
steps 3-6 of this same chain on analytic patches. ``process_batch`` returns a
:class:`BatchResult`; ``process`` runs one frame and returns a :class:`FrameResult` with the
maps for figures and per-step timings; ``process_many`` runs a whole
:class:`~blindspot.radar.source.FrameSource` in batches of :data:`BATCH_FRAMES` frames with
a progress bar and returns the detections and points of every frame (no maps kept).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from blindspot.dsp.cfar import cfar_2d, os_cfar_2d, training_mean
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.dsp.detections import detection_order, local_maxima_at, rank_in_frame
from blindspot.dsp.doa import doa_angles
from blindspot.dsp.doppler_compensation import compensate_tdm
from blindspot.dsp.points import (
    DETECTION_COLUMNS, POINT_COLUMNS, POINT_FIELDS, group_points, moving,
)
from blindspot.arrays import checked_array
from blindspot.dsp.range_doppler import RangeDoppler, RangeDopplerError, detection_map
from blindspot.dsp.snapshots import cell_snapshots, chirp_snapshots
from blindspot.dsp.subbin import ipdft_table, neighbour_offsets
from blindspot.radar.array import VirtualArray
from blindspot.radar.config import RadarConfig
from blindspot.typed_config import ConfigError

def _median(x: np.ndarray) -> float:
    """np.median of all of ``x`` (finite), by one partial sort (np.median's own full path costs
    five times as much on a 256 x 64 map): the middle value, or the mean of the two middle
    values for an even count, as np.median computes it."""
    flat = x.ravel()
    lo, hi = (flat.size - 1) // 2, flat.size // 2
    part = np.partition(flat, (lo, hi))
    return float((part[lo] + part[hi]) / 2)


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


@dataclass
class BatchResult:
    """A processed batch of frames.

    frames, times_s : (F,) frame numbers and times (s) of the batch
    detections : DataFrame ``DETECTION_COLUMNS`` + ``moving`` of all frames, per frame moving
                 first, then strongest; ``angle_deg`` NaN beyond the DOA budget
    points     : DataFrame ``POINT_COLUMNS``, one row per frame where the pedestrian is seen
    power, threshold, noise : (F, range, doppler) float64, mask (F, range, doppler) bool, or
                 None unless the maps were asked for
    spectra    : per frame None or (row of ``detections``, (G,) pseudo-spectrum of the frame's
                 first detection, a moving one), or None unless asked for
    timings_ms : wall time of each step for the whole batch
    """

    frames: np.ndarray
    times_s: np.ndarray
    detections: pd.DataFrame
    points: pd.DataFrame
    power: np.ndarray | None
    threshold: np.ndarray | None
    mask: np.ndarray | None
    noise: np.ndarray | None
    spectra: list | None
    timings_ms: dict[str, float] = field(default_factory=dict)


# Frames processed together by process_many: one MMWCAS frame is 25 MB as complex64, so eight
# (cubes and their range-Doppler maps) stay well under a gigabyte.
BATCH_FRAMES = 8

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
        self.range_table = (ipdft_table(detect.range_window, radar.n_samples)
                            if detect.range_interpolation == "ipdft" else None)
        # FMCW range-Doppler coupling: the beat frequency is 2 S R / c + f_D (f_D = 2 v / lambda,
        # see radar.rd_patch), so a range read off the beat frequency is off by
        # f_D c / (2 S) = v f_c / S: 7.7 mm per m/s on the MMWCAS profile
        self.coupling_s = radar.center_freq_hz / radar.slope_hz_per_s

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
    def range_doppler(self, cubes: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Range and Doppler FFTs of a batch.

        cubes: (frames, chirps, tx, rx, samples) complex.
        Returns (rd (frames, doppler, tx, rx, range) complex64, range profiles (frames, chirps,
        tx, rx, range) when ``detect.snapshots`` is "chirps", else None).
        Raises RangeDopplerError for cubes of another shape (than the radar profile's) or kind,
        or with NaN/inf samples.
        """
        cubes = self._check_cubes(cubes, "range_doppler", ndim=5)
        if self.detect.snapshots == "chirps":
            profiles = self.rd.range_profiles(cubes)
            return self.rd.doppler(profiles), profiles
        return self.rd.native(cubes), None

    def _check_cubes(self, cubes: np.ndarray, where: str, ndim: int) -> np.ndarray:
        """Cubes of the radar profile's shape: (frames, chirps, tx, rx, samples) for ``ndim`` 5,
        one (chirps, tx, rx, samples) for 4; numbers (finiteness: see RangeDoppler)."""
        r = self.radar
        shape = (r.n_chirps, r.n_tx, r.n_rx, r.n_samples)
        axes = (f"one cube (chirps={shape[0]}, tx={shape[1]}, rx={shape[2]}, samples={shape[3]})"
                + (" per frame: (frames, chirps, tx, rx, samples)" if ndim == 5 else ""))
        return checked_array(cubes, "cubes" if ndim == 5 else "cube", RangeDopplerError,
                             where=where, axes=axes, ndim=ndim, kind="numeric", finite=False,
                             lengths={i - 4: n for i, n in enumerate(shape)})

    @staticmethod
    def detection_map(rd: np.ndarray) -> np.ndarray:
        """(frames, doppler, tx, rx, range) -> float64 (frames, range, doppler): sum of |X|^2 over
        the virtual channels (power, never log-magnitude)."""
        return detection_map(np.moveaxis(rd, -1, -4))

    def run_cfar(self, power: np.ndarray):
        """(mask, threshold, noise) of the configured CFAR on (..., range, doppler) maps (any
        leading batch axes), each (..., range, doppler)."""
        c = self.cfar
        if c.domain == "db":
            floor = _median(power)
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

    def select_cells(self, power: np.ndarray, mask: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(frame, range_bin, doppler_bin) (D,) of the detections of (frames, range, doppler)
        maps: CFAR cells inside the range window and, with ``peak_only``, the local maxima of the
        map over their 3 x 3 neighbours (Doppler wraps). Unordered (frame-major)."""
        fi, rb, db = np.nonzero(mask & self.range_ok[:, None])
        if self.detect.peak_only:  # the rule of local_maxima, on the CFAR cells only
            peak = local_maxima_at(power, fi, rb, db)
            fi, rb, db = fi[peak], rb[peak], db[peak]
        return fi, rb, db

    def detection_range(self, power: np.ndarray, frame: np.ndarray, row: np.ndarray,
                        doppler_bin: np.ndarray, range_bin: np.ndarray | None = None, *,
                        column: np.ndarray | None = None) -> np.ndarray:
        """(D,) range (m) of detections at cells (frame, row, doppler_bin) (D,) of
        (frames, rows, doppler) power maps; ``range_bin`` (D,) is each cell's bin in the full
        range axis (default ``row``: the maps are the chain's own; patches of a map pass it)
        and ``column`` (D,) its column in ``power`` (default ``doppler_bin``; maps of a few
        columns pass it).

        ``range_interpolation: none``: the bin's range ``range_bin * range_bin_m``. ``ipdft``:
        ``(range_bin + delta) * range_bin_m - v f_c / S`` with delta the three-point IpDFT offset
        of the range window (:func:`blindspot.dsp.subbin.neighbour_offsets`; 0 on the first and
        last processed bin, where a neighbour is missing) and ``v f_c / S`` the range-Doppler
        coupling of the beat frequency at the cell's Doppler-bin velocity v (chirp slope S,
        centre frequency f_c)."""
        rb = row if range_bin is None else range_bin
        if self.range_table is None:
            return self.range_axis_m[rb]
        col = doppler_bin if column is None else column
        delta = neighbour_offsets(power, frame, row, col, self.range_table)
        delta = np.where((rb > 0) & (rb < self.range_axis_m.size - 1), delta, 0.0)
        return ((rb + delta) * self.radar.range_bin_m
                - self.velocity_axis_mps[doppler_bin] * self.coupling_s)

    def order_detections(self, frame: np.ndarray, power: np.ndarray, doppler_bin: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """(permutation (D,): per frame moving first, then strongest; moving flags (D,) in the
        new order)."""
        mov = moving(self.velocity_axis_mps[doppler_bin], self.detect.min_speed_mps)
        order = detection_order(frame, power, mov)
        return order, mov[order]

    def doa_budget(self, frame_sorted: np.ndarray) -> np.ndarray:
        """(D,) bool: the first ``detect.max_detections`` detections of each frame (sorted by
        frame), whose angles are estimated."""
        return rank_in_frame(frame_sorted) < self.detect.max_detections

    def angles(self, snapshots: np.ndarray, doppler_bin: np.ndarray, *,
               return_spectrum: bool = False):
        """Angles (deg) of detections from their snapshots.

        snapshots: (D, tx, rx, L) channels in firing order, or (D, n_ula, L) already on the ULA
        elements; doppler_bin: (D,) for the TDM-MIMO compensation.
        Returns angles (D,) (NaN where the spectrum has no peak) and, with ``return_spectrum``,
        the pseudo-spectra (D, G) on ``grid_deg``.
        """
        ula = snapshots[:, self.ula_tx, self.ula_rx, :] if snapshots.ndim == 4 else snapshots
        if self.detect.tdm_compensation:
            ula = compensate_tdm(ula, doppler_bin, self.radar.n_chirps, self.radar.loop_period_s,
                                 self.slot_times_s, self.ula_tx)
        o = self.doa
        ang, spec = doa_angles(ula, self.ula_pos, 1, o.n_signals, self.grid_deg, method=o.method,
                               forward_backward=o.forward_backward, subarray=o.subarray,
                               loading=o.loading, peak_order=o.peak_order,
                               return_spectrum=True)
        return (ang[:, 0], spec) if return_spectrum else ang[:, 0]

    # -------------------------------------------------------------------------------- batches
    def process_batch(self, cubes: np.ndarray, frames: np.ndarray | None = None,
                      times_s: np.ndarray | None = None, *, keep_maps: bool = False,
                      keep_spectra: bool = False) -> BatchResult:
        """Run the chain on a batch of cubes (frames, chirps, tx, rx, samples).

        ``frames`` (F,) numbers the frames in the outputs (default 0..F-1), ``times_s`` (F,)
        their times (NaN without). ``keep_maps`` keeps power, threshold, mask and noise
        (F, range, doppler); ``keep_spectra`` the pseudo-spectrum of each frame's first
        detection when it is moving (the pedestrian's candidate; else None).
        """
        cubes = self._check_cubes(cubes, "process_batch", ndim=5)
        n = cubes.shape[0]
        frame_ids = np.arange(n) if frames is None else np.asarray(frames, dtype=np.int64)
        times = np.full(n, np.nan) if times_s is None else np.asarray(times_s, dtype=np.float64)
        if frame_ids.shape != (n,) or times.shape != (n,):
            raise ValueError(f"process_batch: frames {frame_ids.shape} and times_s {times.shape} "
                             f"must be ({n},) for cubes of shape {cubes.shape}")
        t = [time.perf_counter()]
        steps: dict[str, float] = {}

        def lap(name: str) -> None:
            t.append(time.perf_counter())
            steps[name] = (t[-1] - t[-2]) * 1e3

        rd, profiles = self.range_doppler(cubes)
        lap("range_doppler")
        power = self.detection_map(rd)
        lap("map")
        mask, threshold, noise = self.run_cfar(power)
        lap("cfar")
        fi, rb, db = self.select_cells(power, mask)
        pw = power[fi, rb, db]
        order, mov = self.order_detections(fi, pw, db)
        fi, rb, db, pw = fi[order], rb[order], db[order], pw[order]
        snr_db = 10 * np.log10(pw / noise[fi, rb, db])
        range_m = self.detection_range(power, fi, rb, db)
        budget = self.doa_budget(fi)
        lap("detections")
        sel = np.flatnonzero(budget)
        if self.detect.snapshots == "cells":
            x = cell_snapshots(rd, rb[sel], db[sel], self.detect.cell_half, frame=fi[sel],
                               elements=(self.ula_tx, self.ula_rx))  # (D, n_ula, L)
        else:
            x = chirp_snapshots(profiles, rb[sel], frame=fi[sel])
        ang_sel, spec_sel = self.angles(x, db[sel], return_spectrum=True)
        angles = np.full(rb.size, np.nan)
        angles[sel] = ang_sel
        lap("doa")
        velocity = self.velocity_axis_mps[db]
        # every column is a new array of this call, so the tables take them without a copy
        # (copy=False: half of the construction time of such a small table)
        det = pd.DataFrame({
            "frame": frame_ids[fi], "range_bin": rb.astype(np.int64),
            "doppler_bin": db.astype(np.int64), "range_m": range_m,
            "velocity_mps": velocity, "power": pw, "snr_db": snr_db,
            "angle_deg": angles, "moving": mov,
        }, copy=False)
        pts = group_points(fi, range_m, velocity, angles, snr_db, self.detect.min_speed_mps,
                           self.detect.cluster_gap_m, estimator=self.detect.point_estimator)
        # the dict is in POINT_COLUMNS order (frame, time_s, then POINT_FIELDS): no columns=
        # argument, whose reindexing cost more than building the frame
        points = pd.DataFrame({"frame": frame_ids[pts["frame"]], "time_s": times[pts["frame"]],
                               **{k: pts[k] for k in POINT_FIELDS}}, copy=False)
        lap("points")
        spectra = None
        if keep_spectra:  # per frame: its first detection's spectrum when that one is moving
            first = np.flatnonzero(np.r_[True, fi[sel][1:] != fi[sel][:-1]]) if sel.size else sel
            spectra = [None] * n
            for i in first[mov[sel][first]]:  # one entry per frame with a moving first detection
                spectra[fi[sel][i]] = (int(sel[i]), spec_sel[i])
        maps = (power, threshold, mask, noise) if keep_maps else (None,) * 4
        return BatchResult(frames=frame_ids, times_s=times, detections=det, points=points,
                           power=maps[0], threshold=maps[1], mask=maps[2], noise=maps[3],
                           spectra=spectra, timings_ms=steps)

    def process(self, cube: np.ndarray, frame: int = 0, time_s: float = 0.0,
                keep_spectrum: bool = True) -> FrameResult:
        """Run the chain on one cube (chirps, tx, rx, samples): a batch of one frame, with its
        maps (and the first moving detection's pseudo-spectrum) kept for figures."""
        cube = self._check_cubes(cube, "process (process_batch takes a batch)", ndim=4)
        res = self.process_batch(cube[None], np.array([frame]), np.array([time_s]),
                                 keep_maps=True, keep_spectra=keep_spectrum)
        det = res.detections  # one batch: its RangeIndex is already 0..n-1
        kept = res.spectra[0] if res.spectra else None
        return FrameResult(frame=frame, time_s=time_s, detections=det, point=res.points,
                           power=res.power[0], threshold=res.threshold[0], mask=res.mask[0],
                           noise=res.noise[0], spectrum=None if kept is None else kept[1],
                           spectrum_detection=None if kept is None else kept[0],
                           angles_deg=self.grid_deg, range_axis_m=self.range_axis_m,
                           velocity_axis_mps=self.velocity_axis_mps, timings_ms=res.timings_ms)

    def process_frames(self, frames: Iterable[np.ndarray], times_s: np.ndarray | None = None,
                       *, progress: bool = True, total: int | None = None,
                       desc: str = "detect", batch_frames: int = BATCH_FRAMES
                       ) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Detections (all frames) and points (one per frame where the pedestrian is seen) of a
        sequence of cubes, processed in batches of ``batch_frames``; frame i gets time
        ``times_s[i]`` (NaN without)."""
        from tqdm.auto import tqdm

        if not (isinstance(batch_frames, int) and batch_frames >= 1):
            raise ValueError(f"batch_frames: expected a positive integer, found {batch_frames!r}")
        dets, pts, batch, start = [], [], [], 0
        with tqdm(total=total, desc=desc, disable=not progress, unit="frame") as bar:
            for cube in itertools.chain(frames, [None]):
                if cube is not None:
                    batch.append(cube)
                if batch and (cube is None or len(batch) == batch_frames):
                    ids = np.arange(start, start + len(batch))
                    tt = None if times_s is None else np.asarray(times_s, dtype=np.float64)[ids]
                    res = self.process_batch(np.stack(batch), ids, tt)
                    dets.append(res.detections)
                    pts.append(res.points)
                    start += len(batch)
                    bar.update(len(batch))
                    batch = []
        detections = (pd.concat(dets, ignore_index=True) if dets
                      else pd.DataFrame(columns=list(DETECTION_COLUMNS) + ["moving"]))
        points = (pd.concat(pts, ignore_index=True) if pts
                  else pd.DataFrame(columns=list(POINT_COLUMNS)))
        return detections, points.astype({"frame": np.int64, "n_detections": np.int64})

    def process_many(self, source, *, frames: Iterable[int] | None = None,
                     progress: bool = True, batch_frames: int = BATCH_FRAMES
                     ) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Run a FrameSource (all frames, or the given frame indices) in batches of
        ``batch_frames`` with a tqdm progress bar (``progress=False`` silences it); frame numbers
        and times are the source's. Returns (detections of every frame, points: one row per frame
        where the pedestrian is seen)."""
        idx = np.arange(source.n_frames) if frames is None else np.asarray(list(frames))
        cubes = (source.frame(int(i)) for i in idx)
        times = np.asarray(source.times_s, dtype=np.float64)[idx]
        det, points = self.process_frames(cubes, times, progress=progress, total=len(idx),
                                          batch_frames=batch_frames)
        if len(det):
            det["frame"] = idx[det["frame"].to_numpy()]
        if len(points):
            points["frame"] = idx[points["frame"].to_numpy()]
        return det, points
