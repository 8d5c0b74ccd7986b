"""watch: a scene you can watch (issue 44): an animation of a driving scene and of recordings.

The driving scene (watch.scene at watch.ego_speed_kmh, CPNCO at 30 km/h in the pipeline): its
points and tracks (driving_measure, driving_track), each moving track's predicted path with the
calibrated distribution of watch.predictor, the safety stage's warning and AEB request, and a
range-Doppler map every watch.rd_every frames, simulated again (blindspot.synth.driving_maps).
Each recording of watch.recordings from its data/recordings/<name>/ outputs. Writes
reports/animations/<scene>_<speed>kmh.gif and <recording>.gif (.mp4 with watch.format mp4 where
ffmpeg exists) and one frame of the first as reports/figures/watch.png.
`python -m blindspot watch watch.recording=<name>` animates that recording alone.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import time

from blindspot.cli import main_stage
from blindspot.io import atomic_dir
from blindspot.report.animation import (decision_frames, driving_movie, key_frame,
                                        recording_movie, render_movie, render_still, WatchConfig)
from blindspot.stage import StageResult
from blindspot.synth.driving_maps import scene_to_watch


def run(cfg, ctx):
    w, movies, metrics = WatchConfig.from_cfg(cfg), [], {}
    if w.scene and not w.recording:
        s = scene_to_watch(cfg, {
            "truth": ctx.dep("driving/truth.parquet"), "scenes": ctx.dep("scenes.json"),
            "points": ctx.dep("driving/points.parquet"), "tracks": ctx.dep("driving/tracks.parquet"),
            "models": ctx.dep("models.json"), "outcomes": ctx.dep("scene_outcomes.parquet")},
            progress=cfg.progress)
        movies.append((s.name, driving_movie(
            s.title, s.truth, s.cars, s.points, s.tracks, s.predictions,
            decision_frames(s.outcomes, w.scene, predictor=w.predictor, input_name=w.input),
            s.rd, ego_size_m=s.ego_size_m)))
    for n in [w.recording] if w.recording else w.recordings:
        movies.append((n, recording_movie(n, ctx.dep("data/recordings") / n,
                                          every=w.recording_every, max_frames=w.max_frames)))
    with atomic_dir(ctx.out("reports/animations")) as folder:
        for name, movie in movies:
            t0 = time.perf_counter()
            path = render_movie(movie, folder / f"{name}.{w.format}", fps=w.fps, dpi=w.dpi)
            metrics[name] = {"render_s": round(time.perf_counter() - t0, 2),
                             "frames": len(movie.frames),
                             "megabytes": round(path.stat().st_size / 1e6, 3)}
            print(f"watch {name}: {path.name}, {metrics[name]}")
    render_still(movies[0][1], key_frame(movies[0][1]), ctx.out("watch.png"))
    return StageResult(metrics=metrics, artifacts=[ctx.out("watch.png")])


if __name__ == "__main__":
    main_stage(run, "watch")
