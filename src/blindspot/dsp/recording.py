"""A real recording through the detection chain (the recordings stage's work per capture).

:func:`detect_recording` opens a capture (:func:`blindspot.radar.capture.open_recording`), builds
the chain from the recording's radar profile and the ``cfar`` / ``doa`` / ``detect`` groups with
the recording's own overrides laid over them, and returns every frame's detections, the first
frame's maps and a summary.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import OmegaConf

from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.radar.array import array_for
from blindspot.radar.capture import open_recording
from blindspot.radar.config import RadarConfig

__all__ = ["detect_recording"]


def detect_recording(name: str, rec: Any, path: Path, groups: Any, *, progress: bool = False):
    """One capture through the chain: (its detections, its first frame's result, its summary).

    rec    : the recording's entry of ``cfg.recordings`` (kind, radar, options, and optional
             ``cfar`` / ``doa`` / ``detect`` overrides, e.g. a smaller array needs doa.subarray)
    path   : the capture's file or folder
    groups : the composed config (its ``cfar``, ``doa`` and ``detect`` groups)
    Errors name ``recordings.<name>.<key>``.
    """
    where = f"recordings.{name}"
    radar = RadarConfig.from_mapping(rec.radar, where=f"{where}.radar")
    # reader options of the kind (e.g. strict: true to refuse a DCA1000 file with lost packets)
    options = OmegaConf.to_container(rec.get("options") or OmegaConf.create({}))
    try:
        source = open_recording(rec.kind, path, radar, **options)
    except ValueError as exc:
        if "has no option" not in str(exc):
            raise
        raise ValueError(f"config key '{where}.options': {exc}") from None
    chain = DetectionChain.from_config(radar, array_for(radar), *(
        kind.from_mapping(OmegaConf.merge(groups[g], rec.get(g) or {}), where=f"{where}.{g}")
        for g, kind in (("cfar", CfarConfig), ("doa", DoaConfig), ("detect", DetectConfig))))
    det, _ = chain.process_many(source, progress=progress)
    first = chain.process(source.frame(0), frame=0)
    per_frame = det.groupby("frame").size().reindex(range(source.n_frames), fill_value=0)
    strongest = det.sort_values("power", ascending=False).drop_duplicates("frame")
    summary = {
        # where the data lay, relative to the shared folder: no output holds an absolute path
        "file": rec.path if not Path(rec.path).is_absolute() else path.name, "kind": rec.kind, "n_frames": int(source.n_frames),
        "detections_per_frame": float(per_frame.mean()),
        "strongest_range_m": [float(r) for r in strongest.sort_values("frame").range_m],
        "noise_floor_db": float(10 * np.log10(np.median(first.power))),
    }
    print(f"recordings {name}: {source.n_frames} frames, {per_frame.mean():.1f} detections/frame, "
          f"strongest return at {summary['strongest_range_m']} m")
    return det, first, summary
