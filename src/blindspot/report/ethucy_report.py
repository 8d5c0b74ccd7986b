"""The ETH/UCY benchmark's Markdown page (``reports/ethucy.md``): our ADE / FDE beside the
published numbers, the models, the validation splits and the run.

Pure text building from plain values: the results dict of ``reports/metrics/ethucy.json``
(``{model: {fold: {"ade", "fde", "n_windows"}, "avg": {"ade", "fde"}}}``) and the run's details
(what each model fitted per fold, as :class:`blindspot.traj.ethucy_protocol.BenchmarkRun`
gives them). Nothing is computed here. The published numbers come from :mod:`blindspot.report.paper_values`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from blindspot.report.online_label import online_setting_label
from blindspot.report.paper_values import ETHUCY_PUBLISHED

#: how far from nominal a coverage may be and still count as calibrated (percentage points;
#: issue 43's goal for the online ellipses)
COVERAGE_TOLERANCE_PP = 2


def off_nominal(coverage: float, nominal: float) -> bool:
    """Whether a coverage (a share) is more than :data:`COVERAGE_TOLERANCE_PP` points from its
    nominal level (a share); exactly the tolerance counts as within. Raises ValueError for
    either outside [0, 1] or not a finite number."""
    for name, v in (("coverage", coverage), ("nominal", nominal)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
            raise ValueError(f"off_nominal: {name}: expected a share in [0, 1], found {v!r}")
    return abs(coverage - nominal) > COVERAGE_TOLERANCE_PP / 100 + 1e-12

__all__ = ["COVERAGE_TOLERANCE_PP", "off_nominal", "format_table", "compare_to_cvm",
           "format_calibration", "format_seeds", "format_multimodal", "format_report"]

Results = Mapping[str, Mapping[str, Mapping[str, float]]]


#: blocks of a results dict that are not a model's row
_BLOCKS = ("seeds",)


def _models(results: Mapping[str, Any]) -> dict[str, Any]:
    """The per-model rows of a results dict (``"best"``, a model name, and the ``"seeds"`` and
    ``"best_of_<n>"`` blocks left out)."""
    return {m: r for m, r in results.items() if isinstance(r, Mapping) and m not in _BLOCKS
            and not m.startswith("best_of_")}


def format_seeds(results: Mapping[str, Any]) -> str:
    """Markdown table of ``results["seeds"]``: per learned model each seed's fold-averaged
    ADE / FDE and their mean +- sample sd; "" when the block is absent."""
    seeds = results.get("seeds") or {}
    if not seeds:
        return ""
    lines = ["| model | seeds | ADE per seed | FDE per seed | ADE mean +- sd | FDE mean +- sd |",
             "|---|---|---|---|---|---|"]
    for m, r in seeds.items():
        lines.append(f"| {m} | {r['n']} | " + ", ".join(f"{x:.3f}" for x in r["ade"]) + " | "
                     + ", ".join(f"{x:.3f}" for x in r["fde"])
                     + f" | {r['ade_mean']:.3f} +- {r['ade_sd']:.3f} | "
                       f"{r['fde_mean']:.3f} +- {r['fde_sd']:.3f} |")
    return "\n".join(lines)


def format_multimodal(results: Mapping[str, Any],
                      details: Mapping[str, Mapping[str, Mapping[str, Any]]],
                      folds: Sequence[str]) -> str:
    """Markdown tables of the multi-modal models: best-of-N ADE / FDE per fold (seed mean)
    and average +- sd over the seeds; the mixture's NLL and the coverage of its 50/90/95 %
    highest-density regions per fold (uncalibrated, seed mean); the single prediction val chose
    per fold and seed. "" when no ``best_of_<n>`` block."""
    blocks = {k: v for k, v in results.items() if k.startswith("best_of_")
              and isinstance(v, Mapping)}
    if not blocks:
        return ""
    lines: list[str] = []
    for key, rows in blocks.items():
        n = key.removeprefix("best_of_")
        lines += [f"Best-of-{n} ADE / FDE (m; per window the nearest of the model's {n} most "
                  "probable hypotheses, ADE and FDE each on its own; mean over the seeds):", "",
                  "| model | " + " | ".join([*folds, "avg", "sd over seeds"]) + " |",
                  "|---|" + "---|" * (len(folds) + 2)]
        for m, r in rows.items():
            lines.append(f"| {m} | " + " | ".join(_cell(r.get(f)) for f in [*folds, "avg"])
                         + f" | {r['sd']['ade']:.3f} / {r['sd']['fde']:.3f} |")
        lines.append("")
        lines += ["The mixture as a distribution (uncalibrated; per step the mixture of the "
                  "hypotheses' Gaussians): NLL, nats per point, and the coverage of its 50 / 90 "
                  "/ 95 % highest-density regions (Monte Carlo, 100 draws per point); seed mean. "
                  "Point: the single prediction val chose per seed (`mean`: the mixture's "
                  "mean, `mode`: its most probable hypothesis).", "",
                  "| model | " + " | ".join(folds) + " |", "|---|" + "---|" * len(folds)]
        for m in rows:
            cells = []
            for f in folds:
                sc = details[f][m]["fitted"]["seed_scores"]
                mean = {k: sum(x[k] for x in sc) / len(sc) for k in
                        ("mixture_nll", "mixture_coverage_50", "mixture_coverage_90",
                         "mixture_coverage_95")}
                cells.append(f"NLL {mean['mixture_nll']:.2f}; {mean['mixture_coverage_50']:.3f}"
                             f" / {mean['mixture_coverage_90']:.3f} / "
                             f"{mean['mixture_coverage_95']:.3f}; point "
                             + ",".join(x.get("point", "-") for x in sc))
            lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def format_calibration(calibration: Mapping[str, Mapping[str, Mapping[str, Any]]],
                       folds: Sequence[str]) -> str:
    """Markdown table: per method and fold, the empirical coverage of the 50 / 90 / 95 %
    ellipses and the NLL (nats per point), from ``calibration.json``-shaped values; a cell is
    marked ``*`` where a coverage is more than 2 percentage points from nominal
    (:func:`off_nominal`). A method whose rows hold ``online_coverage_*`` (the online ellipses,
    sliding-window conformal or scale tracking, :mod:`blindspot.traj.online`) gets a second
    row, "<method>, online", with the 95 % interval of its 90 % coverage
    (``online_coverage_90_ci95``) and the largest share of its unbounded ellipses where those
    are there."""
    lines = ["| method | " + " | ".join(folds) + " |", "|---|" + "---|" * len(folds)]
    for m, rows in calibration.items():
        for prefix, label in (("", m), ("online_", f"{m}, online")):
            if prefix and not any("online_coverage_50" in (rows.get(f) or {}) for f in folds):
                continue
            cells = []
            for f in folds:
                r = rows.get(f)
                if r is None or f"{prefix}coverage_50" not in r:
                    cells.append("-")
                    continue
                cov = [(r[f"{prefix}coverage_{k}"], k / 100) for k in (50, 90, 95)]
                txt = " / ".join(f"{c:.3f}" + ("*" if off_nominal(c, n) else "")
                                 for c, n in cov)
                if prefix:  # the 90 % interval and the unbounded share, where there are any
                    ci = r.get("online_coverage_90_ci95")
                    u = max(r.get(f"online_unbounded_{k}", 0.0) for k in (50, 90, 95))
                    cells.append(txt + (f"; 90 %: [{ci[0]:.2f}, {ci[1]:.2f}]" if ci else "")
                                 + (f"; unbounded {100 * u:.1f} %" if u > 0 else ""))
                else:
                    cells.append(f"{txt}; NLL {r['nll']:.2f}")
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def format_online_choice(calibration: Mapping[str, Mapping[str, Mapping[str, Any]]],
                         folds: Sequence[str]) -> str:
    """Markdown table of the online setting each method chose on each fold's val scenes and its
    mean distance from nominal there (``online_val_distance``, percentage points), each
    setting as :func:`blindspot.report.online_label.online_setting_label` writes it; "" when no row
    names one."""
    lines = ["| method | " + " | ".join(folds) + " |", "|---|" + "---|" * len(folds)]
    seen = False
    for m, rows in calibration.items():
        cells = []
        for f in folds:
            r = rows.get(f) or {}
            cell = online_setting_label(r)
            if cell == "-":
                cells.append(cell)
                continue
            seen = True
            d = r.get("online_val_distance")
            cells.append(cell + (f" ({100 * d:.2f} pp)" if d is not None else ""))
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines) if seen else ""


def _cell(d: Mapping[str, float] | None) -> str:
    return "-" if d is None else f"{d['ade']:.2f} / {d['fde']:.2f}"


def format_table(results: Results, folds: Sequence[str], published: bool = True) -> str:
    """Markdown table of ADE / FDE (m) per fold and average, ours then (``published``) the
    literature's."""
    cols = [*folds, "avg"]
    lines = ["| model | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for m, rows in _models(results).items():
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
    for m, rows in _models(results).items():
        if m == "cvm":
            continue
        d_ade, d_fde = rows["avg"]["ade"] - base["ade"], rows["avg"]["fde"] - base["fde"]
        verdict = ("beats" if d_ade < 0 and d_fde < 0 else
                   "does not beat" if d_ade >= 0 and d_fde >= 0 else "splits with")
        lines.append(f"- {m} {verdict} CVM on the test-fold average: ADE {d_ade:+.3f} m, "
                     f"FDE {d_fde:+.3f} m.")
    return lines + [""] if lines else []


#: how each ``ethucy.calibration`` method is described on the page
_CALIBRATION_WORDS = {
    "mle": "a per-step covariance scale, `fit_step_scale` method `mle`",
    "quantile": "a per-step covariance scale, `fit_step_scale` method `quantile`",
    "mixture": "a per-step scale mixture of the forecast's Gaussians, `fit_scale_mixture`",
    "conditional": "one per-step scale mixture per class of observed speed (standing, slow, "
                   "walking, brisk, fast), `fit_conditional_scale_mixture`",
}


def format_report(results: Results, validation: Results,
                  details: Mapping[str, Mapping[str, Mapping[str, Any]]], folds: Sequence[str],
                  lstm: Mapping[str, Any] | None, command: str, seconds: float | None, *,
                  seq2seq: Mapping[str, Any] | None = None,
                  calibration: Mapping[str, Mapping[str, Mapping[str, Any]]] | None = None,
                  calibration_method: str | None = None,
                  ablation: str | None = None) -> str:
    """The Markdown page: table, protocol, fitted values, validation splits, calibration,
    command.

    Args:
        results: the benchmark's results (the content of ``reports/metrics/ethucy.json``; its
            ``"best"`` entry names the model chosen on the val splits).
        validation: the same scores on each fold's val split, in the same shape.
        details: ``{fold: {model: {"n_windows", "seconds", "fitted": {...}}}}``; ``fitted``
            holds ``process_psd_m2_s3`` for the Kalman filter; ``val_rmse_m`` for the
            next-point LSTM (``lstm_rollout``); ``best_epochs`` for the direct predictors
            (``lstm``, ``gru``, ``mlp``); ``step_scale`` for every model with a distribution.
        folds: the folds run, in column order.
        lstm: the next-point LSTM's settings as a dict, or None when it was not run.
        command: how the run was started, quoted on the page.
        seconds: wall time of the run, quoted with each model's share; None leaves it out (the
            pipeline's page, whose bytes a rerun reproduces; the stage logs it to MLflow).
        seq2seq: the direct predictor's settings as a dict, or None.
        calibration: ``{method: {fold: {"coverage_50", "coverage_90", "coverage_95", "nll",
            ...}}}`` (the calibration on the test scenes), or None.
        calibration_method: how the per-step scale was fitted on val (quoted).
        ablation: a Markdown block (the measured ablation table and its command), or None.
    """
    models = _models(results)
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
    ]
    if isinstance(results.get("best"), str):
        val_avg = "; ".join(f"{m} {rows['avg']['ade']:.4f} / {rows['avg']['fde']:.4f}"
                            for m, rows in _models(validation).items() if "avg" in rows)
        parts += [f"Best model (lowest mean ADE on the folds' val splits, chosen without the "
                  f"test scenes): **{results['best']}**"
                  + (f" (val ADE / FDE averages, m: {val_avg})." if val_avg else "."), ""]
    parts += ["## Models", ""]
    if "cvm" in models:
        parts.append("- **cvm**: constant velocity from the last two observed positions, "
                     "`x_t - x_(t-1)` (Schöller et al. 2020).")
    if "kalman" in models:
        parts.append("- **kalman**: constant-velocity Kalman filter (white-noise acceleration, "
                     "dt = 0.4 s), process noise fitted per fold on that fold's train windows "
                     "to minimise their ADE.")
        fitted = ", ".join(f"{f} {details[f]['kalman']['fitted']['process_psd_m2_s3']:.3g}"
                           for f in folds)
        parts.append(f"  Fitted process noise q (m^2/s^3), meas_std 0.05 m: {fitted}.")
    direct = [m for m in ("lstm", "gru", "mlp", "transformer") if m in models]
    if seq2seq is not None and direct:
        enc = {"lstm": "an LSTM encoder", "gru": "a GRU encoder",
               "mlp": "a dense (MLP) encoder over the flattened inputs",
               "transformer": (f"a transformer encoder ({seq2seq.get('num_layers')} pre-norm "
                               f"self-attention layer(s) of {seq2seq.get('attention_heads')} "
                               "heads over the observed steps, a learned position embedding)")}
        n_seeds = (results.get("seeds") or {}).get(direct[0], {}).get("n", 1)
        for m in direct:
            parts.append(
                f"- **{m}**: direct multi-step predictor (`blindspot.traj.seq2seq`) with "
                f"{enc[m]}: the 8 observed positions in each track's heading frame"
                + (" as displacements" if seq2seq.get("inputs") == "displacement" else "")
                + ", all 12 future positions emitted at once"
                + (" as the correction to constant velocity" if seq2seq.get("residual") else "")
                + ", trained on the 8 -> 12 " + str(seq2seq.get("loss", "ade")).upper()
                + (" with mirrored copies and left/right-symmetrised predictions"
                   if seq2seq.get("mirror") else "")
                + (f", a Gaussian head per step (NLL weight {seq2seq['nll_weight']})"
                   if seq2seq.get("nll_weight") else "")
                + (f"; the mean of {seq2seq.get('ensemble')} members trained with consecutive "
                   "seeds, each" if (seq2seq.get("ensemble") or 1) > 1 else
                   f"; one network per seed ({n_seeds} seeds from {seq2seq.get('seed')}; "
                   "the table gives their mean, the distributions are the first seed's),")
                + f" up to {seq2seq.get('epochs')} epochs, kept at the epoch of lowest val ADE."
                + " Epochs kept per fold (per seed): "
                + ", ".join(f"{f} " + str([x["best_epochs"][0] for x in
                                           details[f][m]["fitted"]["seed_scores"]]
                                          if "seed_scores" in details[f][m]["fitted"]
                                          else details[f][m]["fitted"].get("best_epochs"))
                            for f in folds)
                + ".")
        if "mix" in models:
            parts.append(
                "- **mix**: the multi-modal predictor: the same direct predictor with "
                f"{(seq2seq.get('mix_cell') or 'the MLP')} encoder and "
                f"{seq2seq.get('mix_modes')} hypotheses, each a Gaussian path, with their "
                "probabilities (a mixture, `blindspot.traj.mixture`), trained by relaxed "
                "winner-takes-all on the ADE, cross-entropy on the winner and the winner's "
                "Gaussian NLL, each hypothesis started at a k-means anchor of the training "
                "futures' deviations from constant velocity. Its single prediction is the "
                "mixture's mean or its most probable hypothesis, whichever val prefers; its "
                "ellipses come from the mixture's second moment about that prediction. Epochs "
                "kept per fold (per seed): "
                + ", ".join(f"{f} " + str([x["best_epochs"][0] for x in
                                           details[f]["mix"]["fitted"]["seed_scores"]])
                            for f in folds) + ".")
        shown = {k: v for k, v in dict(seq2seq).items()
                 if k not in ("cell", "mix_cell", "mix_modes")}
        parts.append(f"  Settings (`ethucy.seq2seq`; the encoder is set by the model key): "
                     f"`{json.dumps(shown)}`. What each choice is worth (ablation table, measured "
                     "on the val and test splits, with its command): `conf/ethucy/standard.yaml`.")
    if lstm is not None and "lstm_rollout" in models:
        heading = lstm["frame"] == "heading"
        parts += [
            "- **lstm_rollout**: the project's next-point LSTM (window 8), trained per fold on "
            "every fully observed 9-frame stretch of the train split, validated on the val "
            "split, rolled out 12 steps autoregressively"
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
            "  One-step val RMSE per coordinate (m) "
            + ", ".join(f"{f} {details[f]['lstm_rollout']['fitted']['val_rmse_m']:.4f}"
                        for f in folds) + ".",
        ]
    if (seeds := format_seeds(results)):
        parts += ["", "## Seeds", "",
                  "Each learned model trained with every seed; its ADE / FDE averaged over the "
                  "folds per seed, and the mean and sample sd over the seeds (the table above "
                  "gives the mean):", "", seeds]
    if (multi := format_multimodal(results, details, folds)):
        parts += ["", "## Multi-modal predictions", "", multi]
    parts += ["", "## Validation splits", "",
              "The same metrics on each fold's val split (parts of the training scenes, never "
              "the test scene): settings are to be chosen on these, not on the test table.",
              "", format_table(validation, folds, published=False)]
    if calibration:
        parts += ["", "## Calibration (test scenes)", "",
                  "Empirical coverage of the 50 / 90 / 95 % ellipses of each predicted point "
                  "(all 12 steps) and the mean negative log-likelihood (nats per point) on each "
                  "test scene, after a calibration fitted on the fold's val split"
                  + (f" ({_CALIBRATION_WORDS.get(calibration_method, calibration_method)})"
                     if calibration_method else "")
                  + ". `*`: more than 2 percentage points from nominal. cvm: a heteroscedastic "
                  "noise model of its errors (along/cross-track covariance per step, scaled "
                  "by the history's speed and acceleration) fitted on val; kalman: the filter's "
                  "own F P F^T + Q + R; lstm / gru / mlp / transformer: the Gaussian head plus "
                  "the ensemble spread; mix: the mixture's second moment about its single "
                  "prediction. "
                  "Rows \"online\": the same forecasts' online ellipses, each test scene a "
                  "stream, each future point known at its own frame; they use the scene's past "
                  "outcomes, never the one being scored. Two kinds, chosen per fold and method "
                  "on the val scenes: scale tracking (`blindspot.traj.scale_tracker`): the val "
                  "scores' quantile at each step times one scale per level, which tracks the "
                  "scene's quantile (Angelopoulos et al. 2023's quantile tracker on the log "
                  "radius, every revealed outcome one step) and is corrected by the miss rate "
                  "the ellipses delivered so far (bounded); or sliding-window ACI "
                  "(`blindspot.traj.conformal`, Gibbs & Candès 2021): the conformal quantiles of "
                  "the last revealed outcomes (the val scores before any, taking the scene's "
                  "scale once a few of its own are known), at levels moved by ACI. \"90 %: [lo, hi]\": the 95 % interval of the 90 % "
                  "coverage, a bootstrap over the scene's pedestrians (one pedestrian's windows "
                  "overlap and are not independent draws). "
                  "\"unbounded\": the share of points whose ellipse at some level is infinite "
                  "(ACI asked for more than its window can give).",
                  "", format_calibration(calibration, folds),
                  *(["", "Online setting each method chose on each fold's own val scenes "
                     "(scale: the tracker's step / the correction's gain; ACI: step / "
                     "window / rescale after; in brackets its mean distance from nominal there, "
                     "each val scene met as a new scene):", "", choice]
                    if (choice := format_online_choice(calibration, folds)) else []),
                  "", "Reliability figure: `reports/figures/ethucy_reliability.png`."]
    if ablation:
        parts += ["", "## What helped (ablations)", "", ablation.strip()]
    parts += ["", "## Run", "", f"Command: `{command}`", ""]
    if seconds is not None:
        timing = ", ".join(f"{m} {sum(details[f][m]['seconds'] for f in folds):.0f} s"
                           for m in models)
        parts += [f"Wall time {seconds:.0f} s ({timing}).", ""]
    return "\n".join(parts)
