"""Running the detection chain over simulated scenes, one worker process per scene."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial

import pandas as pd

from blindspot.dsp.chain import DetectionChain, FrameResult
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import SceneConfig
from blindspot.radar.simulator import SimulatedSource


@dataclass
class SceneDetections:
    """Detections of every frame of one scene (``scene`` and ``time_s`` columns added), and the
    full result of one frame kept for figures (None unless asked for)."""

    scene: str
    detections: pd.DataFrame
    kept_frame: FrameResult | None


def detect_scene(scene: SceneConfig, radar: RadarConfig, cfar: CfarConfig, doa: DoaConfig,
                 detect: DetectConfig, sim: SimConfig,
                 keep_frame: int | None = None, progress: bool = False) -> SceneDetections:
    """Simulate the scene frame by frame and run the chain on batches of frames."""
    chain = DetectionChain(radar, array_for(radar), cfar, doa, detect)
    source = SimulatedSource.from_config(scene, radar, sim)
    det, _ = chain.process_many(source, progress=progress)
    det = det.assign(scene=scene.name, time_s=source.times_s[det["frame"].to_numpy()])
    kept = None
    if keep_frame is not None:
        if not 0 <= keep_frame < source.n_frames:
            raise ValueError(f"frame {keep_frame} to keep is outside scene {scene.name!r} "
                             f"(0..{source.n_frames - 1})")
        kept = chain.process(source.frame(keep_frame), frame=keep_frame,
                             time_s=float(source.times_s[keep_frame]))
    return SceneDetections(scene.name, det, kept)


def detect_scenes(scenes: Mapping[str, SceneConfig], radar: RadarConfig, cfar: CfarConfig,
                  doa: DoaConfig, detect: DetectConfig, sim: SimConfig, *,
                  keep: tuple[str, int] | None = None, jobs: int = 1,
                  progress: bool = False) -> list[SceneDetections]:
    """:func:`detect_scene` for every scene, in ``jobs`` processes (the typed configs are frozen
    dataclasses, so they pickle); ``keep`` = (scene, frame) whose full frame result is kept."""
    from blindspot.parallel import parallel_map

    items = [(sc, keep[1] if keep and keep[0] == name else None) for name, sc in scenes.items()]
    work = partial(_detect_item, radar=radar, cfar=cfar, doa=doa, detect=detect, sim=sim,
                   progress=progress)
    return parallel_map(work, items, jobs)


def _detect_item(item, **kwargs) -> SceneDetections:
    scene, keep_frame = item
    return detect_scene(scene, keep_frame=keep_frame, **kwargs)
