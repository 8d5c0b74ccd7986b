"""The ETH/UCY benchmark's Markdown page (``reports/ethucy.md``): our ADE / FDE beside the
published numbers, the models, the validation splits and the run.

Pure text building from plain values: the results dict of ``reports/metrics/ethucy.json``
(``{model: {fold: {"ade", "fde", "n_windows"}, "avg": {"ade", "fde"}}}``) and the run's details
(what each model fitted per fold, as :class:`blindspot.traj.ethucy_benchmark.BenchmarkRun`
gives them). Nothing is computed here. The published numbers come from :mod:`blindspot.report.paper_values`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from blindspot.report.paper_values import ETHUCY_PUBLISHED

__all__ = ["format_table", "compare_to_cvm", "format_report"]

Results = Mapping[str, Mapping[str, Mapping[str, float]]]


def _cell(d: Mapping[str, float] | None) -> str:
    return "-" if d is None else f"{d['ade']:.2f} / {d['fde']:.2f}"


def format_table(results: Results, folds: Sequence[str], published: bool = True) -> str:
    """Markdown table of ADE / FDE (m) per fold and average, ours then (``published``) the
    literature's."""
    cols = [*folds, "avg"]
    lines = ["| model | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for m, rows in results.items():
        lines.append(f"| {m} (ours) | " + " | ".join(_cell(rows.get(c)) for c in cols) + " |")
    if published:
        for m, rows in ETHUCY_PUBLISHED.items():
            lines.append(f"| published: {m} | " + " | ".join(_cell(rows.get(c)) for c in cols)
                         + " |")
    return "\n".join(lines)


def compare_to_cvm(results: Results) -> list[str]:
    """Report lines: each model's average ADE/FDE minus the CVM's (negative = better)."""
    if "cvm" not in results:
        return []
    base = results["cvm"]["avg"]
    lines = []
    for m, rows in results.items():
        if m == "cvm":
            continue
        d_ade, d_fde = rows["avg"]["ade"] - base["ade"], rows["avg"]["fde"] - base["fde"]
        verdict = ("beats" if d_ade < 0 and d_fde < 0 else
                   "does not beat" if d_ade >= 0 and d_fde >= 0 else "splits with")
        lines.append(f"- {m} {verdict} CVM on the test-fold average: ADE {d_ade:+.3f} m, "
                     f"FDE {d_fde:+.3f} m.")
    return lines + [""] if lines else []


def format_report(results: Results, validation: Results,
                  details: Mapping[str, Mapping[str, Mapping[str, Any]]], folds: Sequence[str],
                  lstm: Mapping[str, Any] | None, command: str, seconds: float) -> str:
    """The Markdown page: table, protocol, fitted values, validation splits, command.

    Args:
        results: the benchmark's results (the content of ``reports/metrics/ethucy.json``).
        validation: the same scores on each fold's val split, in the same shape.
        details: ``{fold: {model: {"n_windows", "seconds", "fitted": {...}}}}``; ``fitted``
            holds ``process_psd_m2_s3`` for the Kalman filter, ``val_rmse_m``, ``val_ade_m``
            and ``val_fde_m`` for the LSTM.
        folds: the folds run, in column order.
        lstm: the LSTM's settings as a dict (field name -> value), or None when it was not run.
        command: how the run was started, quoted on the page.
        seconds: wall time of the run.
    """
    parts = [
        "# ETH/UCY benchmark",
        "",
        "ADE / FDE in metres (observe 8 = 3.2 s, predict 12 = 4.8 s; leave-one-scene-out; "
        "Social-GAN windows; single deterministic prediction). `avg` is the unweighted mean of "
        "the folds.",
        "",
        format_table(results, folds),
        "",
        "Test windows per fold: "
        + ", ".join(f"{f} {next(iter(details[f].values()))['n_windows']}" for f in folds) + ".",
        "",
        *compare_to_cvm(results),
        "## Models",
        "",
    ]
    if "cvm" in results:
        parts.append("- **cvm**: constant velocity from the last two observed positions, "
                     "`x_t - x_(t-1)` (Schöller et al. 2020).")
    if "kalman" in results:
        parts.append("- **kalman**: constant-velocity Kalman filter (white-noise acceleration, "
                     "dt = 0.4 s), process noise fitted per fold on that fold's train windows "
                     "to minimise their ADE.")
    if "kalman" in results:
        fitted = ", ".join(f"{f} {details[f]['kalman']['fitted']['process_psd_m2_s3']:.3g}"
                           for f in folds)
        parts.append(f"  Fitted process noise q (m^2/s^3), meas_std 0.05 m: {fitted}.")
    if lstm is not None and "lstm" in results:
        heading = lstm["frame"] == "heading"
        parts += [
            "- **lstm**: the project's next-point LSTM (window 8), trained per fold on every "
            "fully observed 9-frame stretch of the train split, validated on the val split, "
            "rolled out 12 steps autoregressively"
            + (" in each window's heading frame (origin at the last point, +x along the last "
               "step; recomputed at every rollout step)" if heading else "")
            + (", predicting the correction to constant velocity" if heading
               and lstm["residual"] else "")
            + (", mirrored copies in training and left/right-symmetrised predictions"
               if heading and lstm["mirror"] else "")
            + (f", windows scaled by their last step (floor {lstm['speed_floor']} m)"
               if heading and lstm["speed_floor"] else "")
            + (f"; the mean of {lstm['ensemble']} LSTMs trained with consecutive seeds"
               if lstm["ensemble"] > 1 else "")
            + f". Settings: `{json.dumps(dict(lstm))}`.",
            "  On each fold's val split (for model selection; never the test scene): one-step "
            "RMSE per coordinate (m) "
            + ", ".join(f"{f} {details[f]['lstm']['fitted']['val_rmse_m']:.4f}" for f in folds)
            + "; 12-step ADE / FDE (m) "
            + ", ".join(f"{f} {details[f]['lstm']['fitted']['val_ade_m']:.2f} / "
                        f"{details[f]['lstm']['fitted']['val_fde_m']:.2f}" for f in folds)
            + ".",
        ]
    parts += ["", "## Validation splits", "",
              "The same metrics on each fold's val split (parts of the training scenes, never "
              "the test scene): settings are to be chosen on these, not on the test table.",
              "", format_table(validation, folds, published=False)]
    timing = ", ".join(f"{m} {sum(details[f][m]['seconds'] for f in folds):.0f} s" for m in results)
    parts += ["", "## Run", "", f"Command: `{command}`", "",
              f"Wall time {seconds:.0f} s ({timing}).", ""]
    return "\n".join(parts)
