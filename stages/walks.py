"""walks: many randomised occluded walks of the paper's scene (issue 10, section 3), drawn around
the car (blindspot.synth.scene_walks), measured through the paths stage's reduced chain, filled,
predicted and scored with bootstrap intervals, with the calibrated distributions and each
predictor's online ellipses (the calibration stage's) beside (blindspot.synth.walk_scores)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
import time

from blindspot.cli import main_stage
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.io import save_figure, write_json, write_parquet, write_text
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.report.walks_report import benchmark_figure, benchmark_table
from blindspot.stage import StageResult
from blindspot.synth.scene_walks import car_scene_walks
from blindspot.synth.walk_scores import per_walk_table, score_walks, walk_lines
from blindspot.traj.config import EvalConfig, WalksConfig
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.seq2seq import Seq2SeqEnsemble
from blindspot.typed_config import jobs


def run(cfg, ctx):
    t0 = time.perf_counter()
    bench, radar = WalksConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg)
    car = next(s for s in load_scenes(cfg.scene).values() if s.with_car)
    walks, measured = car_scene_walks(bench, radar, car, CfarConfig.from_cfg(cfg),
                                      DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                                      seed=int(cfg.seed), jobs=jobs(cfg),
                                      progress=bool(cfg.progress))
    t_radar = time.perf_counter() - t0
    metrics, extra, scores, names, fills = score_walks(
        walks, measured, ev=EvalConfig.from_cfg(cfg), bench=bench, dt=radar.frame_period_s,
        lstm=LSTMPredictor.load(ctx.dep("train/model.pt")).with_workers(jobs(cfg)),
        direct=Seq2SeqEnsemble.load(ctx.dep("train_direct/model.pt")),
        records=json.loads(ctx.dep("models.json").read_text()),
        val_scores=ctx.dep("val_scores.npz"),
        online_settings=json.loads(ctx.dep("online.json").read_text()),
        seed=int(cfg.seed), train_seed=int(cfg.train.seed))
    write_json(ctx.out("benchmark.json"), metrics)
    write_json(ctx.out("benchmark_paired.json"), extra)
    whole = {**metrics, **extra}                    # what the table and the figure read
    write_parquet(ctx.out("per_walk.parquet"), per_walk_table(scores, walks))
    write_text(ctx.out("benchmark.md"), benchmark_table(whole, "dvc repro benchmark"))
    three_walks = json.loads(ctx.dep("evaluate.json").read_text())   # the paper's three walks
    save_figure(benchmark_figure(whole, three_walks), ctx.out("benchmark.png"), dpi=110)
    seconds = time.perf_counter() - t0
    print("\n".join([*walk_lines(metrics, names), f"walks: {len(walks)} walks in {seconds:.0f} s "
                                                   f"({t_radar:.0f} s radar)"]))
    return StageResult(metrics={"n_walks": len(walks), "seconds": seconds,
                                **{n: {k: v["mean"] for k, v in metrics[n].items()}
                                   for n in (*names, *fills)}})


if __name__ == "__main__":
    main_stage(run, "walks")
