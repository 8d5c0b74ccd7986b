"""watch: a scene you can watch (issue 44): a driving scene as an animation.

watch.scene at watch.ego_speed_kmh (CPNCO at 30 km/h in the pipeline): its points and tracks
(driving_measure, driving_track), each moving track's predicted path with the calibrated
distribution of watch.predictor, the safety stage's warning and AEB request, and a range-Doppler
map every watch.rd_every frames, simulated again (blindspot.synth.driving_maps); drawn by
blindspot.report.animation. Writes reports/animations/<scene>_<speed>kmh.gif (.mp4 with
watch.format=mp4 where ffmpeg exists) and the frame after the AEB request as
reports/figures/watch.png. A recording's animation: the recordings stage (`animate: true`).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import time

from blindspot.cli import main_stage
from blindspot.io import atomic_dir
from blindspot.report.animation import (WatchConfig, decision_frames, driving_movie, key_frame,
                                        render_movie, render_still)
from blindspot.stage import StageResult
from blindspot.synth.driving_maps import scene_to_watch


def run(cfg, ctx):
    w = WatchConfig.from_cfg(cfg)
    s = scene_to_watch(cfg, {
        "truth": ctx.dep("driving/truth.parquet"), "scenes": ctx.dep("scenes.json"),
        "points": ctx.dep("driving/points.parquet"), "tracks": ctx.dep("driving/tracks.parquet"),
        "models": ctx.dep("models.json"), "outcomes": ctx.dep("scene_outcomes.parquet")},
        progress=cfg.progress)
    movie = driving_movie(
        s.title, s.truth, s.cars, s.points, s.tracks, s.predictions,
        decision_frames(s.outcomes, w.scene, predictor=w.predictor, input_name=w.input),
        s.rd, ego_size_m=s.ego_size_m)
    t0 = time.perf_counter()
    with atomic_dir(ctx.out("reports/animations")) as folder:
        path = render_movie(movie, folder / f"{s.name}.{w.format}", fps=w.fps, dpi=w.dpi)
        metrics = {"render_s": round(time.perf_counter() - t0, 2), "frames": len(movie.frames),
                   "megabytes": round(path.stat().st_size / 1e6, 3),
                   "rd_maps": len(s.rd["frame"]), "predicted_rows": len(s.predictions)}
    render_still(movie, key_frame(movie), ctx.out("watch.png"))
    print(f"watch {s.name}: {path.name}, {metrics}")
    return StageResult(metrics=metrics, artifacts=[ctx.out("watch.png")])


if __name__ == "__main__":
    main_stage(run, "watch")
