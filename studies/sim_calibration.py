"""sim_paths calibration per method with 95 % bootstrap intervals over the held-out paths.

    BLINDSPOT_SHARED=/work/shared python studies/sim_calibration.py \\
        mixture,quantile

Needs the calibration stage's deps checked out (data/paths/paths.parquet, data/windows/
{train,val}.parquet, data/train/model.pt). For each calibration method (conf/calibration
`scale_method`), fits every scene predictor on the validation pairs as the stage does and prints
the coverage of the 50/90/95 % ellipses on the held-out paths, each with a 95 % percentile
bootstrap interval that resamples whole paths (the points of one path are not independent).

Conclusion: on held-out paths of the training kind the calibrated ellipses cover 0.44-0.54 /
0.93-0.95 / 0.96-0.98 (50 / 90 / 95 %), +-7 points at 50 % for CV and Kalman and +-15 for the
LSTM over the 21 paths: 2 points cannot be resolved on so few paths (README, calibration).
"""
import blindspot, sys
import numpy as np, pandas as pd
from omegaconf import OmegaConf
from blindspot.radar.config import RadarConfig
from blindspot.traj.baselines import prediction_methods
from blindspot.traj.config import CalibrationConfig, DatasetConfig, EvalConfig
from blindspot.traj.calibration import calibrate, path_pairs
from blindspot.traj.distribution import mahalanobis_sq, chi2_2dof_radius_sq
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.windows import WindowSet
import torch; torch.set_num_threads(1)
cfg = OmegaConf.load("params.yaml")
c = CalibrationConfig.from_cfg(cfg); window = DatasetConfig.from_cfg(cfg).window
truth, measured, _ = table_to_arrays(pd.read_parquet("data/paths/paths.parquet"))
ids = {s: np.unique(WindowSet.load(f"data/windows/{s}.parquet").path_id) for s in ("train", "val")}
ids["test"] = np.setdiff1d(np.arange(len(truth)), np.concatenate([ids["train"], ids["val"]]))
hv, fv = path_pairs(measured[ids["val"]], truth[ids["val"]], window, c.horizon_frames, c.stride)
per = [path_pairs(measured[i:i+1], truth[i:i+1], window, c.horizon_frames, c.stride) for i in ids["test"]]
lstm = LSTMPredictor.load("data/train/model.pt")
rng = np.random.default_rng(0)
for method in sys.argv[1].split(","):
    cal = calibrate(prediction_methods(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s, lstm), hv, fv, scale_method=method, scale_level=0.9,
                    cv_fit_points=EvalConfig.from_cfg(cfg).cv_fit_points)
    for name, p in cal.items():
        ins = []
        for h, f in per:
            fc = p.predict_distribution(h, f.shape[1])
            d2 = mahalanobis_sq(fc, f)
            r2 = p.radius_sq((0.5, 0.9, 0.95), f.shape[1])[:, None, :]
            ins.append(np.stack([(d2 <= r2[i]).sum() for i in range(3)] + [d2.size]))
        ins = np.array(ins, float)                                  # (P, 4)
        cov = ins[:, :3].sum(0) / ins[:, 3].sum()
        b = rng.integers(0, len(ins), (2000, len(ins)))
        bc = ins[b, :3].sum(1) / ins[b, 3].sum(1)[:, None]
        lo, hi = np.percentile(bc, [2.5, 97.5], axis=0)
        print(method, name, " ".join(f"{c:.3f} [{l:.3f}, {h:.3f}]" for c, l, h in zip(cov, lo, hi)))
