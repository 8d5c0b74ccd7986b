"""detect: range-Doppler maps, CA-CFAR detections and their MUSIC angles for the six scenes.

Each scene's frames are simulated in memory one at a time and go through the detection chain
(blindspot.dsp.chain), one worker process per scene (`jobs`). MUSIC runs here, while the frame is
in memory (regenerating every frame in `localise` would double the simulation time); `localise`
turns the detections into points. The maps of one frame are kept for Fig. 6 (a-c).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.cli import main_stage
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.dsp.frame_io import write_frame_result
from blindspot.io import write_parquet
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import load_scenes
from blindspot.stage import StageResult
from blindspot.synth.scene_detection import detect_scenes
from blindspot.typed_config import jobs


def run(cfg, ctx):
    scenes = load_scenes(cfg.scene)
    fig_scene, fig_frame = cfg.eval.fig06_scene, int(cfg.eval.fig06_frame)
    if fig_scene not in scenes:
        raise ValueError(f"config key 'eval.fig06_scene' = {fig_scene!r}: expected one of {list(scenes)}")
    results = detect_scenes(scenes, RadarConfig.from_cfg(cfg), CfarConfig.from_cfg(cfg),
                            DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                            SimConfig.from_cfg(cfg), keep=(fig_scene, fig_frame),
                            jobs=jobs(cfg), progress=cfg.progress)
    detections = pd.concat([r.detections for r in results], ignore_index=True)
    kept = next(r.kept_frame for r in results if r.kept_frame is not None)
    write_frame_result(ctx.out("fig06_frame.npz"), kept, scene=fig_scene)
    write_parquet(ctx.out("fig06_detections.parquet"), kept.detections.assign(scene=fig_scene))
    write_parquet(ctx.out("detections.parquet"), detections)
    per_scene = detections.groupby("scene", sort=False).agg(n=("frame", "size"), moving=("moving", "sum"))
    print("detect: detections (moving) per scene: "
          + ", ".join(f"{s} {r.n} ({r.moving})" for s, r in per_scene.iterrows()))
    return StageResult(metrics={f"detections_per_frame.{s}": r.n / scenes[s].n_frames
                                for s, r in per_scene.iterrows()})


if __name__ == "__main__":
    main_stage(run, "detect")
