"""The chain's settings on the independent tuning draw (issue 40): each run of the tuning draw's
stage with an override beside the committed one, per predictor the avoided-after-visible and
false-activation rates at the configured AEB threshold and at the operating point chosen for
the false-activation budget (:func:`blindspot.safety.operating_point.choose_operating_point`),
and the median first point -> moving. Prints figures, asserts nothing.

    python -m blindspot safety_tuning tracker.moving.approach_probability=null \\
        hydra.run.dir=/tmp/abl/approach_off      # about 10 min on 2 cores; one per override
    BLINDSPOT_SHARED=../shared .venv/bin/python studies/tuning_ablation.py /tmp/abl/* \\
        [--predictors track_state,constant_velocity,lstm_direct] [--target 0.03]

Each run's directory holds reports/metrics/safety_tuning.json (the stage writes there, not over
the pipeline's); its settings digest says which settings it was made with. The committed draw
is reports/metrics/safety_tuning.json.

Conclusion (2026-12-06, tuning draw, seed 2, 306 + 306 scenes;
docs/studies/first-point-to-brake.md, sixth pass): of the four parts the second and third passes
chose on the main draw's even half, the approach test and the coasting limit earn their place
(without them the best at the 3 % budget falls from 0.418 to 0.373); without the range-rate
update the best there is a tie (0.415) and false activations at threshold 0.5 rise by 2.6-5.8
points; the crossing prior moves 0-3 scenes of 306. All kept.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from blindspot.safety.draws import draw_curve
from blindspot.safety.operating_point import choose_operating_point

REPO = Path(__file__).resolve().parents[1]


def summary(block: dict, predictor: str, target: float) -> str:
    """One predictor's line of a draw block (safety_tuning.json)."""
    b = block[predictor]
    op = choose_operating_point(draw_curve(block, predictor), target)
    flags = ("" if op["target_met"] else " (budget missed: the fewest false activations)") + (
        " (top of the grid)" if op["top_of_grid"] else "")
    return (f"{predictor:18s} configured threshold: {b['avoided_after_visible_rate']:.3f} at "
            f"{b['false_activation_rate']:.3f}; <= {target:.0%}: threshold "
            f"{op['aeb_threshold']:.6g}, {op['avoided_after_visible_rate']:.3f} at "
            f"{op['false_activation_rate']:.3f}{flags}; first point -> moving "
            f"{b['first_point_to_moving_s_median']:.2f} s")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="hydra.run.dir of each override's run")
    ap.add_argument("--predictors", default="track_state,constant_velocity,lstm_direct")
    ap.add_argument("--target", type=float, default=0.03)
    args = ap.parse_args(argv)
    paths = [REPO / "reports" / "metrics" / "safety_tuning.json"]
    paths += [r / "reports" / "metrics" / "safety_tuning.json" for r in args.runs]
    blocks = {}
    for path in dict.fromkeys(paths):                       # each file once, in order
        if not path.is_file():
            raise SystemExit(f"{path}: no safety_tuning.json (run the stage with "
                             f"hydra.run.dir={path.parents[2]})")
        blocks[path] = json.loads(path.read_text())
    draw = ("seed", "n_intruding", "n_non_intruding")
    committed = blocks[paths[0]]
    for path, block in blocks.items():
        if any(block.get(k) != committed.get(k) for k in draw):
            found = ", ".join(f"{k} {block.get(k)}" for k in draw)
            want = ", ".join(f"{k} {committed.get(k)}" for k in draw)
            raise SystemExit(f"{path}: another draw ({found}) than the committed one ({want})")
    for path, block in blocks.items():
        name = "committed" if path == paths[0] else str(path.parents[2])
        print(f"{name} (seed {block['seed']}, {block['n_intruding']} + "
              f"{block['n_non_intruding']} scenes, settings {block['chain_digest'][:10]})")
        for p in args.predictors.split(","):
            print("  " + summary(block, p, args.target))


if __name__ == "__main__":
    main()
