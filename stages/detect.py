"""detect: range-Doppler maps, CA-CFAR detections and their MUSIC angles for the six scenes.

Each scene's frames are simulated in memory one at a time and go through the detection chain
(blindspot.dsp.chain), one worker process per scene (`jobs`). MUSIC runs here, while the frame is
in memory (regenerating every frame in `localise` would double the simulation time); `localise`
turns the detections into points. The maps of one frame are kept for Fig. 6 (a-c).
"""

import numpy as np
import pandas as pd

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.synth.scene_detection import detect_scenes
from blindspot.io import atomic_open, write_parquet


def run(cfg):
    scenes = experiment.scenes(cfg)
    fig_scene, fig_frame = cfg.eval.fig06_scene, int(cfg.eval.fig06_frame)
    if fig_scene not in scenes:
        raise ValueError(f"config key 'eval.fig06_scene' = {fig_scene!r}: expected one of {list(scenes)}")
    results = detect_scenes(scenes, experiment.radar(cfg), experiment.cfar(cfg), experiment.doa(cfg),
                            experiment.detect(cfg), experiment.sim(cfg), keep=(fig_scene, fig_frame),
                            jobs=cfg.jobs, progress=cfg.progress)
    detections = pd.concat([r.detections for r in results], ignore_index=True)
    kept = next(r.kept_frame for r in results if r.kept_frame is not None)
    with atomic_open(experiment.data_path(cfg, "detect", "fig06_frame.npz"), "wb") as f:
        np.savez_compressed(
            f, power=kept.power, threshold=kept.threshold, mask=kept.mask,
            range_axis_m=kept.range_axis_m, velocity_axis_mps=kept.velocity_axis_mps,
            spectrum=kept.spectrum if kept.spectrum is not None else np.zeros(0),
            angles_deg=kept.angles_deg,
            spectrum_detection=-1 if kept.spectrum_detection is None else kept.spectrum_detection,
            scene=fig_scene, frame=fig_frame, time_s=kept.time_s)
    write_parquet(experiment.data_path(cfg, "detect", "fig06_detections.parquet"),
                  kept.detections.assign(scene=fig_scene))
    write_parquet(experiment.data_path(cfg, "detect", "detections.parquet"), detections)
    per_scene = detections.groupby("scene", sort=False).agg(n=("frame", "size"), moving=("moving", "sum"))
    tracking.current().log_metrics(
        {f"detections_per_frame.{s}": r.n / scenes[s].n_frames for s, r in per_scene.iterrows()})
    print("detect: detections (moving) per scene: "
          + ", ".join(f"{s} {r.n} ({r.moving})" for s, r in per_scene.iterrows()))


if __name__ == "__main__":
    main_stage(run, "detect")
