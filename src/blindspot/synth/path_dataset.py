"""The paper's training data set: random pedestrian paths, every point measured by the radar chain.

Paths are drawn in chunks of fixed size, each measured with its own seed derived from the config
seed and the chunk index, so the bytes do not depend on how many worker processes run the chunks.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pandas as pd

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.parallel import parallel_map
from blindspot.radar.config import RadarConfig
from blindspot.synth.path_measurement import PathMeasurement, PedestrianModel, measure_paths
from blindspot.traj.paths import MOTIONS, PathSet

CHUNK_PATHS = 16


def measure_path_set(paths: PathSet, radar: RadarConfig, cfar: CfarConfig, doa: DoaConfig,
                     detect: DetectConfig, *,
                     pedestrian: PedestrianModel, seed: int, jobs: int = 1,
                     progress: bool = False, occluders: np.ndarray | None = None,
                     occlusion_db: float = 50.0,
                     frames: np.ndarray | None = None) -> PathMeasurement:
    """:func:`measure_paths` over chunks of :data:`CHUNK_PATHS` paths in ``jobs`` processes.

    ``paths``: a :class:`PathSet` or anything with an ``xy`` (P, T, 2) array of truth paths;
    ``occluders``: (P, E, 2) footprint per path and ``occlusion_db`` its loss (see
    :func:`measure_paths`), or None; ``frames`` (P, T) bool, the frames to measure, or None."""
    xy = paths.xy
    starts = list(range(0, len(xy), CHUNK_PATHS))
    seeds = np.random.SeedSequence(seed).generate_state(len(starts), dtype=np.uint32)
    work = partial(_measure_chunk, radar=radar, cfar=cfar, doa=doa, detect=detect,
                   pedestrian=pedestrian, occlusion_db=occlusion_db)
    items = [(xy[s:s + CHUNK_PATHS], int(k),
              None if occluders is None else occluders[s:s + CHUNK_PATHS],
              None if frames is None else frames[s:s + CHUNK_PATHS])
             for s, k in zip(starts, seeds)]
    parts = parallel_map(work, items, jobs, progress="paths (chunks)" if progress else None)
    return PathMeasurement(**{f: np.concatenate([getattr(p, f) for p in parts])
                              for f in PathMeasurement.__dataclass_fields__})


def _measure_chunk(item, *, radar, cfar, doa, detect, pedestrian, occlusion_db
                   ) -> PathMeasurement:
    xy, seed, occ, frames = item
    return measure_paths(xy, radar, None, cfar, doa, detect, pedestrian=pedestrian, seed=seed,
                         occluders=occ, occlusion_db=occlusion_db, frames=frames,
                         progress=False)


def path_table(paths: PathSet, measured: PathMeasurement, frame_period_s: float) -> pd.DataFrame:
    """Long table: one row per path point, truth and measurement side by side."""
    p, t = measured.xy.shape[:2]
    return pd.DataFrame({
        "path_id": np.repeat(np.arange(p), t),
        "point": np.tile(np.arange(t), p),
        "time_s": np.tile(np.arange(t) * frame_period_s, p),
        "motion": np.repeat(np.asarray(MOTIONS)[paths.motion], t),
        "x_true_m": paths.xy[..., 0].ravel(), "y_true_m": paths.xy[..., 1].ravel(),
        "x_m": measured.xy[..., 0].ravel(), "y_m": measured.xy[..., 1].ravel(),
        "range_m": measured.range_m.ravel(), "angle_deg": measured.angle_deg.ravel(),
        "velocity_mps": measured.velocity_mps.ravel(), "snr_db": measured.snr_db.ravel(),
        "n_detections": measured.n_detections.ravel(),
    })
