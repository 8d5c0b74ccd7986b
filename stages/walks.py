"""walks: many randomised occluded walks of the paper's scene (issue 10, section 3).

``benchmark.n_walks`` walks (car pose and size, speed, turn angle, where the walk turns and when
the prediction starts drawn per walk; blindspot.synth.scene_walks) go through the paths stage's
validated reduced radar chain with the car as occluder, then through the interpolate and predict
stages' own library calls batched over walks (blindspot.synth.walk_scores); predicted by the
paper's methods (eval.prediction_methods) and by the scenes' direct multi-step LSTM (lstm_direct,
the train_direct stage's: pre-trained on ETH/UCY, then fine-tuned on the radar paths unless
direct.finetune is false). Every metric's
mean over walks gets a 95 % percentile-bootstrap interval, and the differences between methods a
paired bootstrap of per-walk differences (blindspot.traj.bootstrap). The predictive distributions
calibrated on validation paths by the calibration stage are scored on the walks too (coverage
of the 50/90/95 % ellipses, NLL): the walks are never used to fit them; beside them the
adaptive conformal ellipses (blindspot.traj.conformal), the walks met one after another, each
walk's ellipses from the outcomes of the walks before it and the validation scores.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
import time

import numpy as np
import pandas as pd

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.traj.baselines import kalman_baseline, prediction_methods
from blindspot.traj.config import CalibrationConfig, EvalConfig, WalksConfig
from blindspot.typed_config import jobs
from blindspot.cli import main_stage
from blindspot.io import save_figure, write_json, write_parquet, write_text
from blindspot.report.walks_report import benchmark_figure, benchmark_table
from blindspot.stage import StageResult
from blindspot.synth.path_measurement import PedestrianModel
from blindspot.synth.walk_scores import COVERAGE_LEVELS, score_scene_walks
from blindspot.synth.scene_walks import draw_scene_walks, measure_scene_walks
from blindspot.traj.bootstrap import bootstrap_means, paired_differences
from blindspot.traj.calibration import from_record
from blindspot.traj.conformal import AdaptiveConformal
from blindspot.traj.direct import NAME as DIRECT
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.predictor import ConstantVelocityTail
from blindspot.traj.seq2seq import Seq2SeqEnsemble

COMMAND = "dvc repro benchmark"


def measured_walks(cfg, bench, *, seed: int, jobs: int, progress: bool = False):
    """(walks, measured): ``bench``'s occluded walks of the paper's car scene drawn with
    ``seed`` and measured through the paper's chain with the first scene that has the car (its
    pedestrian model and occlusion loss), on ``jobs`` worker processes; what this stage and the
    benchmarks that score other models on its walks (bench_pretrain, bench_pretrain_direct,
    bench_walk_scores) draw."""
    radar = RadarConfig.from_cfg(cfg)
    car = next(s for s in load_scenes(cfg.scene).values() if s.with_car)
    walks = draw_scene_walks(bench, radar.frame_period_s, seed=seed)
    measured = measure_scene_walks(
        walks, radar, CfarConfig.from_cfg(cfg), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
        pedestrian=PedestrianModel.from_scene(car), occlusion_db=car.occlusion_db, seed=seed,
        jobs=jobs, progress=progress)
    return walks, measured


def run(cfg, ctx):
    t0 = time.perf_counter()
    bench = WalksConfig.from_cfg(cfg)
    ev = EvalConfig.from_cfg(cfg)
    radar = RadarConfig.from_cfg(cfg)
    dt = radar.frame_period_s
    walks, measured = measured_walks(cfg, bench, seed=int(cfg.seed), jobs=jobs(cfg),
                                     progress=bool(cfg.progress))
    t_radar = time.perf_counter() - t0
    lstm = LSTMPredictor.load(ctx.dep("train/model.pt")).with_workers(jobs(cfg))
    kalman = kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s)
    # the paper's methods and the scenes' direct multi-step LSTM (the train_direct stage's; one
    # network call per prediction). Its forecast counts from the last point seen, and a few
    # walks were last seen long before the prediction time (3 of the 300 need more than its 40
    # steps): those steps continue at its last step's velocity.
    direct = Seq2SeqEnsemble.load(ctx.dep("train_direct/model.pt"))
    predictors = {**prediction_methods(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s, lstm),
                  DIRECT: ConstantVelocityTail(direct, direct.cfg.horizon)}
    records = json.loads(ctx.dep("models.json").read_text())   # fitted by the calibration stage
    distributions = {n: from_record(records[n], p, n) for n, p in predictors.items()
                     if n in records}
    with np.load(ctx.dep("val_scores.npz")) as z:              # where the online ellipses start
        priors = {n: z[n] for n in distributions if n in z.files}
    c = CalibrationConfig.from_cfg(cfg)
    online = AdaptiveConformal(COVERAGE_LEVELS, c.online_gamma, c.online_window,
                               c.online_rescale_after)
    # each network of the seed ensemble alone too (member i: seed train.seed + i), on the same
    # walks and the same filled histories: the spread a single training run would carry
    members = ({f"lstm_member{i}": lstm.member(i) for i in range(lstm.n_members)}
               if lstm.n_members > 1 else {})
    scores, _ = score_scene_walks(
        walks, measured, predictors={**predictors, **members}, interpolation_methods=ev.interpolation_methods,
        prediction_input=ev.prediction_input, gap_predictor=lstm, smoother=kalman.smooth_batch,
        horizon=bench.horizon_frames, dt_s=dt, horizons_s=ev.horizons_s,
        distributions=distributions, threads=bench.threads, online=online, priors=priors)
    boot = dict(n_boot=bench.n_bootstrap, level=bench.ci_level, seed=int(cfg.seed))
    names = list(predictors)
    pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    fills = [f"fill_{m}" for m in ev.interpolation_methods]
    pairs += [(a, b) for i, a in enumerate(fills) for b in fills[i + 1:]]
    # benchmark.json keeps issue 10's shape, {"n_walks": N, method: {metric: {mean, ci95}}};
    # what does not fit it (differences between methods, the members' spread) has its own file
    metrics = {"n_walks": len(walks), **bootstrap_means(scores, **boot)}
    extra: dict = {"paired": paired_differences(scores, pairs, **boot)}
    if members:
        spread = {k: [metrics[m][k]["mean"] for m in members]
                  for k in ("path_error_mean_m", "ade_1s", "ade_2s", "fde_2s")}
        extra["lstm_members"] = {"n_members": len(members), "seeds_from": int(cfg.train.seed),
                                 **{k: {"min": min(v), "max": max(v)} for k, v in spread.items()}}
    write_json(ctx.out("benchmark.json"), metrics)
    write_json(ctx.out("benchmark_paired.json"), extra)
    whole = {**metrics, **extra}                    # what the table and the figure read
    per_walk = pd.DataFrame({f"{m}.{k}": v for m, per in scores.items() for k, v in per.items()})
    per_walk.insert(0, "walk", range(len(walks)))
    per_walk.insert(1, "speed_mps", walks.speed_mps)
    per_walk.insert(2, "turn_deg", walks.turn_deg)
    write_parquet(ctx.out("per_walk.parquet"), per_walk)
    write_text(ctx.out("benchmark.md"), benchmark_table(whole, COMMAND))
    three_walks = json.loads(ctx.dep("evaluate.json").read_text())   # the paper's three walks
    save_figure(benchmark_figure(whole, three_walks), ctx.out("benchmark.png"), dpi=110)
    seconds = time.perf_counter() - t0
    for name in names:
        m = metrics[name]
        print(f"benchmark {name}: paper's metric {m['path_error_mean_m']['mean']:.3f} m "
              f"{m['path_error_mean_m']['ci95']}, ADE 1 s {m['ade_1s']['mean']:.3f} m, "
              f"FDE 2 s {m['fde_2s']['mean']:.3f} m")
    print(f"walks: {len(walks)} walks in {seconds:.0f} s ({t_radar:.0f} s radar)")
    return StageResult(metrics={"n_walks": len(walks), "seconds": seconds,
                                **{n: {k: v["mean"] for k, v in metrics[n].items()}
                                   for n in (*names, *fills)}})


if __name__ == "__main__":
    main_stage(run, "walks")
