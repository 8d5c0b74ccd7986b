"""How fast each ETH/UCY fold's walkers go, and how far constant velocity overshoots them (issue
43): per fold and split, the windows' last observed step as a speed (median, p90) and, on the
test windows whose walker moves (last step of 0.1 m or more), constant velocity's final-point error
along the walker's heading (mean, negative: CV ends past the walker) and across it (mean
magnitude). Prints figures, asserts nothing; a few seconds.

    BLINDSPOT_SHARED=../shared .venv/bin/python studies/ethucy_pace.py

Conclusion (2026-12-06, docs/studies/ethucy.md, "Issue 43, third pass"): eth's test walkers go a
median 1.20 m/s over their last observed step (p90 2.36), faster than any train or val split
(medians 0.51-0.88, p90 1.19-1.39 m/s), and constant velocity's final point ends 2.0 m past them
along the heading on average (0.2-0.6 m on the other folds): the Social-GAN files step eth's
frames by 10 where the original annotation steps by 6. Pace alone does not make a fold hard:
zara1's test walkers go 1.07 m/s and constant velocity overshoots them by 0.23 m.
"""

from __future__ import annotations

import argparse

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np

from blindspot.traj.ethucy import FOLDS, FRAME_PERIOD_S as STEP_S, OBS_LEN as OBS
from blindspot.traj.ethucy import default_data_dir, load_split

MOVING_STEP_M = 0.1   # m, a last step this long or longer: the walker moves


def pace(xy: np.ndarray) -> tuple[float, float]:
    """(median, p90) m/s of the windows' (N, 20, 2) last observed step."""
    v = np.linalg.norm(xy[:, OBS - 1] - xy[:, OBS - 2], axis=-1) / STEP_S
    return float(np.median(v)), float(np.percentile(v, 90))


def cv_overshoot(xy: np.ndarray) -> tuple[float, float, int]:
    """(mean along-heading error, mean |cross-heading error|, windows) m of constant velocity's
    final point on the windows whose last observed step is at least MOVING_STEP_M."""
    step = xy[:, OBS - 1] - xy[:, OBS - 2]
    length = np.linalg.norm(step, axis=-1)
    keep = length >= MOVING_STEP_M
    step, length, xy = step[keep], length[keep], xy[keep]
    h = step / length[:, None]
    n = np.stack([-h[:, 1], h[:, 0]], axis=-1)
    err = xy[:, -1] - (xy[:, OBS - 1] + step * (xy.shape[1] - OBS))
    return float((err * h).sum(-1).mean()), float(np.abs((err * n).sum(-1)).mean()), int(keep.sum())


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    data = default_data_dir()
    print("| fold | train m/s median / p90 | val | test | CV final error on moving test windows: "
          "along / |across| (m), windows |")
    print("|---|---|---|---|---|")
    for fold in FOLDS:
        cells = []
        for split in ("train", "val", "test"):
            xy = load_split(data, fold, split, neighbours=0).xy
            cells.append("%.2f / %.2f" % pace(xy))
        along, across, n = cv_overshoot(load_split(data, fold, "test", neighbours=0).xy)
        print(f"| {fold} | " + " | ".join(cells) + f" | {along:.2f} / {across:.2f}, {n} |")


if __name__ == "__main__":
    main()
