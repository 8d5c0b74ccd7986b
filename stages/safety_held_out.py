"""safety_held_out: the independent held-out Monte-Carlo draw (issue 40;
blindspot.safety.held_out): scenario.monte_carlo.held_out_seed, held_out_scenes_per_cell scenes
per cell of the same grid, through the radar measurement, the tracker and the decision with the
settings chosen on the tuning draw; writes the held-out block of safety.json
(reports/metrics/safety_held_out.json, git-tracked so that a fresh clone's repro reuses it)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.config import WarningConfig
from blindspot.track.config import TrackerConfig
from blindspot.typed_config import jobs
from blindspot.cli import main_stage
from blindspot.io import write_json
from blindspot.safety.assess import assess, logged_metrics
from blindspot.safety.held_out import (held_out_block, held_out_noise, held_out_scenes,
                                       held_out_truth)
from blindspot.safety.outcome import body_boxes
from blindspot.safety.predict import stage_predictors
from blindspot.safety.risk import EgoShape
from blindspot.stage import StageResult
from blindspot.synth.driving_measurement import measure_driving
from blindspot.synth.driving_tracks import driving_tracks


def run(cfg, ctx):
    group, named = load_scenarios(cfg.scenario)
    radar, w, n_jobs = (RadarConfig.from_cfg(cfg, "driving_radar"), WarningConfig.from_cfg(cfg),
                        jobs(cfg))
    dt, seed = float(radar.frame_period_s), group.monte_carlo.held_out_seed
    scenes = held_out_scenes(group, named)
    truth, meta = held_out_truth(scenes, group, dt)
    points = measure_driving(scenes, group, radar, CfarConfig.from_cfg(cfg, "driving_cfar"),
                             DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                             held_out_noise(EgoMotionConfig.from_cfg(cfg), seed),
                             adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                             jobs=n_jobs, progress=cfg.progress).points
    tables, _ = driving_tracks(truth, points, TrackerConfig.from_cfg(cfg), w.oracle, seed=w.seed,
                               frame_period_s=dt, jobs=n_jobs, where="held-out points")
    res = assess(truth, meta, {"tracker": tables["tracks"]},
                 stage_predictors(cfg, ctx.dep, jobs=n_jobs), w, bodies=body_boxes(group),
                 shape=EgoShape(group.ego.width_m, group.ego.length_m),
                 points=points[["scene", "frame", "source"]], frame_period_s=dt,
                 figure_scene=scenes[0].name, draw_seed=seed, ncap_inputs=())
    block = held_out_block(res.metrics, seed)
    write_json(ctx.out("safety_held_out.json"), block)
    for name, h in block.items():
        if isinstance(h, dict):
            print(f"safety_held_out {name}: avoided after visible "
                  f"{h['avoided_after_visible_rate']:.3f}, false activations "
                  f"{h['false_activation_rate']:.3f}, first point -> moving "
                  f"{h['first_point_to_moving_s_median']} s, -> AEB "
                  f"{h['first_point_to_aeb_s_median']} s")
    return StageResult(metrics=logged_metrics({"held_out": block}))


if __name__ == "__main__":
    main_stage(run, "safety_held_out")
