"""The benchmark and calibration stages end to end on a tiny setting (a few walks, an untrained
LSTM): every declared out written, the JSON shapes other checks read."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from blindspot import config
from blindspot.traj.config import DirectConfig, LSTMConfig
from blindspot.stage import StageContext, read_dvc_stages
from blindspot.traj.lstm import LSTMPredictor, LSTMRegressor, NormStats

REPO = Path(__file__).resolve().parents[2]


def _load_stage(name: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"stage_{name}", REPO / "stages" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """Composed config (tiny profile, 4 walks) and a work dir holding an untrained LSTM and direct
    LSTM, their calibration records and the three-walk metrics the benchmark's figure shows."""
    root = tmp_path_factory.mktemp("bench")
    cfg = config.compose(["profile=tiny", "walks.n_walks=3", "walks.n_bootstrap=200",
                          "calibration.stride=2",   # enough val pairs for the scale mixture
                          "jobs=1", "progress=false"], config_dir=REPO / "conf")
    torch.manual_seed(0)
    stats = NormStats(True, "displacement")
    lstm = LSTMPredictor(LSTMRegressor(LSTMConfig.from_cfg(cfg)), stats,  # a 2-seed ensemble
                         more=[(LSTMRegressor(LSTMConfig.from_cfg(cfg)), stats)])
    lstm.save(root / "data/train/model.pt")
    from blindspot.traj.seq2seq import Seq2SeqEnsemble, Seq2SeqModel, Seq2SeqNet

    direct = DirectConfig.from_cfg(cfg).model          # untrained: the residual head is CV
    Seq2SeqEnsemble([Seq2SeqModel(Seq2SeqNet(direct), direct) for _ in range(2)],
                    name="lstm_direct").save(root / "data/train_direct/model.pt")
    (root / "reports/metrics").mkdir(parents=True)
    (root / "reports/metrics/calibration_ethucy.json").write_text(json.dumps(   # ethucy stage's
        {"cvm": {"zara1": {"coverage_50": 0.5, "coverage_90": 0.9, "coverage_95": 0.95, "nll": 1.0}}}))
    (root / "reports/metrics/evaluate.json").write_text(json.dumps(
        {"kalman": {"ade_1s": 0.3, "path_error_mean_m": 0.5}}))
    return cfg, root


def _context(stage: str, root: Path) -> StageContext:
    files = read_dvc_stages(REPO)[stage]
    files = type(files)(files.stage, tuple(str(root / p) for p in files.deps),
                        tuple(str(root / p) for p in files.outs))
    for p in files.outs:
        Path(p).parent.mkdir(parents=True, exist_ok=True)
    return StageContext(files)


def test_calibration_then_benchmark_on_a_tiny_setting(tiny):
    cfg, root = tiny
    rng = np.random.default_rng(0)
    # a small path table as the paths stage writes it, and its val / test windows
    from blindspot.traj.windows import WindowSet

    T, P = 120, 6
    t = np.arange(T) * 0.1
    heading = rng.uniform(0, 2 * np.pi, P)
    truth = np.stack([np.cos(heading)[:, None] * 1.2 * t, 8 + np.sin(heading)[:, None] * 1.2 * t],
                     axis=-1)
    meas = truth + rng.normal(0, 0.05, truth.shape)
    table = pd.DataFrame({
        "path_id": np.repeat(np.arange(P), T), "point": np.tile(np.arange(T), P),
        "time_s": np.tile(t, P), "motion": "perpendicular",
        "x_true_m": truth[..., 0].ravel(), "y_true_m": truth[..., 1].ravel(),
        "x_m": meas[..., 0].ravel(), "y_m": meas[..., 1].ravel(),
        **{c: np.nan for c in ("range_m", "angle_deg", "velocity_mps", "snr_db")},
        "n_detections": 1})
    (root / "data/paths").mkdir(parents=True, exist_ok=True)
    table.to_parquet(root / "data/paths/paths.parquet")
    (root / "data/windows").mkdir(parents=True, exist_ok=True)
    for split, ids in (("train", [0]), ("val", [1, 2, 3]), ("test", [4])):
        x = np.zeros((len(ids), 50, 2), np.float32)
        WindowSet(x, np.zeros((len(ids), 2), np.float32), np.array(ids),
                  np.zeros(len(ids), np.int64)).save(root / f"data/windows/{split}.parquet")
    ctx = _context("calibration", root)
    _load_stage("calibration").run(cfg, ctx)
    ctx.check_outs()
    cal = json.loads((root / "reports/metrics/calibration.json").read_text())
    assert set(cal) >= {"lstm", "constant_velocity", "kalman", "lstm_direct"}
    assert set(cal["lstm_direct"]["sim_paths"]) >= {"coverage_90", "nll"}   # its own head
    assert set(cal["kalman"]["sim_paths"]) >= {"coverage_50", "coverage_90", "coverage_95", "nll"}
    assert cal["kalman"]["sim_paths"]["n_paths"] == 2          # test path 4 and spare path 5
    assert cal["constant_velocity"]["zara1"]["coverage_90"] == 0.9  # ETH/UCY folds merged in

    ctx = _context("walks", root)
    _load_stage("walks").run(cfg, ctx)
    ctx.check_outs()
    m = json.loads((root / "reports/metrics/benchmark.json").read_text())
    assert m["n_walks"] == 3
    # issue 10's shape: every key but n_walks a method of {metric: {mean, ci95}}
    assert all(set(e) >= {"mean", "ci95"} for k, v in m.items() if k != "n_walks"
               for e in v.values())
    m.update(json.loads((root / "reports/metrics/benchmark_paired.json").read_text()))
    for method in ("lstm", "constant_velocity", "kalman", "fill_bidirectional"):
        for entry in m[method].values():
            assert set(entry) >= {"mean", "ci95"} and len(entry["ci95"]) == 2
    assert {"ade_0.5s", "fde_2s", "path_error_mean_m", "coverage_90", "nll"} <= set(m["kalman"])
    # the adaptive conformal ellipses beside, from the calibration stage's validation scores
    with np.load(root / "data/calibration/val_scores.npz") as z:
        assert set(z.files) == {"lstm", "constant_velocity", "kalman", "lstm_direct"}
        assert z["kalman"].shape[1] == cfg.calibration.horizon_frames
    for level in (50, 90, 95):
        entry = m["kalman"][f"online_coverage_{level}"]
        assert 0.0 <= entry["mean"] <= 1.0 and len(entry["ci95"]) == 2
    # each predictor's online setting, chosen in the calibration stage, named in the table
    chosen = json.loads((root / "data/calibration/online.json").read_text())
    assert set(chosen) == set(z.files) and m["online_setting"] == chosen
    assert cal["kalman"]["sim_paths"]["online_method"] == chosen["kalman"]["online_method"]
    assert "online_val_distance" in cal["kalman"]["sim_paths"]
    table = (root / "reports/tables/benchmark.md").read_text()
    assert "each method's setting is the one it chose among `calibration.online_*`" in table
    assert any(f"| Kalman (CV) | {label} " in table for label in ("ACI", "scale"))
    assert "lstm - kalman" in m["paired"]
    # the scenes' direct LSTM beside the paper's methods: scored, calibrated, paired
    assert {"path_error_mean_m", "ade_1s", "fde_2s", "coverage_90", "online_coverage_90"} <= \
        set(m["lstm_direct"])
    assert "kalman - lstm_direct" in m["paired"]
    assert "direct LSTM (ours)" in (root / "reports/tables/benchmark.md").read_text()
    # each ensemble member scored alone, its range summarised, no pairs of members
    assert set(m["lstm_member1"]) >= {"path_error_mean_m", "ade_1s"}
    assert m["lstm_members"]["n_members"] == 2
    lo, hi = (m["lstm_members"]["path_error_mean_m"][k] for k in ("min", "max"))
    assert lo <= hi and not any("member" in pair for pair in m["paired"])
    assert "seed 1 |" in (root / "reports/tables/benchmark.md").read_text()
    assert (root / "reports/tables/benchmark.md").read_text().count("|") > 20
