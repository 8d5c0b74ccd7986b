"""The report page (``reports/README.md``): every figure and table, and our numbers beside the paper's.

Pure text building: :func:`build_page` takes the metrics files already read (dicts, ``None`` for a
file that does not exist yet, e.g. the ETH/UCY benchmark) and the tables' Markdown, and returns
the page. Image links are relative to the page (``figures/fig04.png``). Every row says which
command regenerates it. Where our numbers differ from the paper's, :func:`differences` says so in
plain words, computed from the same metrics so the text can never disagree with the table.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from blindspot.report.walks_report import benchmark_methods
from blindspot.report.paper_values import (
    ETHUCY_CVM,
    FIG6E_ACCUMULATED_FRAMES,
    PATH_ERROR_FIRST_BELOW_M,
    PATH_ERROR_MEAN_M,
    VAL_RMSE,
    WINDOW,
)
from blindspot.report.style import method_label
from blindspot.report.tables import markdown_table

__all__ = [
    "FigureEntry",
    "FIGURES",
    "command",
    "summary_rows",
    "differences",
    "build_page",
]

Metrics = Mapping[str, Any] | None


@dataclass(frozen=True)
class FigureEntry:
    """A figure on the page: the stage that makes it, its path relative to the page, a caption."""

    stage: str
    path: str
    title: str
    caption: str


FIGURES: tuple[FigureEntry, ...] = (
    FigureEntry("fig04", "figures/fig04.png", "Fig. 4: LSTM predictions on simulated paths",
                f"(a)(b) approaching, (c)(d) receding, (e) perpendicular: a window of {WINDOW.value} radar points "
                "(black) and the LSTM rolled out autoregressively (red) against the true continuation "
                "(dashed). Paths from the test split (validation split when the test split lacks a "
                "motion); none was seen in training."),
    FigureEntry("fig06", "figures/fig06.png", "Fig. 6: detection chain on one frame",
                "(a) range-velocity map, (b) power over the CA-CFAR threshold with the car (static, "
                "near zero velocity) and the pedestrian (moving) detections, (c) MUSIC pseudo-spectrum "
                "of the pedestrian's detection with the estimated and true angle, (d) the pedestrian's "
                f"point after static-clutter removal, (e) the points of {FIG6E_ACCUMULATED_FRAMES.value} frames, "
                "blue to red by time."),
    FigureEntry("fig07", "figures/fig07.png", "Fig. 7: the three directions without and with the car",
                "Top: no car, the points form a continuous path. Bottom: with the car, no points while "
                "the pedestrian is hidden (orange: true positions while hidden)."),
    FigureEntry("fig08", "figures/fig08.png", "Fig. 8: interpolation of the hidden frames",
                "Observed radar points (black), truth (dashed) and each method's filled frames; the "
                "legend gives the mean error on the hidden frames."),
    FigureEntry("fig09", "figures/fig09.png", "Fig. 9: future path prediction",
                "Input track (black: the points seen before the prediction start, gaps filled by "
                "eval.prediction_input; the paper filled them with its forward LSTM), LSTM "
                "predictions (red) and baselines, truth dashed; legend: the paper's metric per scene."),
    FigureEntry("fig10", "figures/fig10.png", "Fig. 10: error against prediction step",
                "(a) the paper's metric (distance to the nearest actual point; solid: against the truth, "
                "dotted: against the radar track of the same walk without the car) with the paper's "
                f"mean {PATH_ERROR_MEAN_M.value} m; (b) the time-aligned error."),
)

TABLE_STAGES = {"table1": "Table 1: LSTM hyper-parameters", "table2": "Table 2: radar parameters"}


def command(stage: str, short: bool = False) -> str:
    """The ways to regenerate a stage's output, as Markdown code (``short``: DVC only)."""
    if short:
        return f"`dvc repro {stage}`"
    return f"`dvc repro {stage}` or `python -m blindspot {stage}`"


def _m(value: Any, digits: int = 3) -> str:
    """A length in metres, or "n/a"."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{float(value):.{digits}f} m"


def _get(d: Metrics, *keys: str) -> Any:
    for k in keys:
        if not isinstance(d, Mapping) or k not in d:
            return None
        d = d[k]
    return d


def _methods(evaluate: Metrics) -> list[str]:
    return [k for k in (evaluate or {}) if k != "paper" and isinstance(evaluate[k], Mapping)]


def _baselines(metrics: Metrics, ours: str, path: Sequence[str], digits: int = 3) -> str:
    """"label x m; label y m" for every method of ``metrics`` except ``ours``."""
    parts = []
    for method in metrics or {}:
        if method in (ours, "paper", "n_windows", "all_scenes"):
            continue
        value = _get(metrics, method, *path)
        if value is not None:
            parts.append(f"{method_label(method)} {_m(value, digits)}")
    return "; ".join(parts)


def summary_rows(metrics: Mapping[str, Metrics]) -> list[tuple[str, str, str, str, str]]:
    """Rows (quantity, paper, ours, baselines, command) of the page's summary table.

    ``metrics``: the parsed JSON of
    reports/metrics/{localise,train,interpolate,evaluate,ethucy,benchmark,calibration,train_direct}.json
    under those keys; a missing key or ``None`` gives a row saying the stage has not run.
    """
    rows: list[tuple[str, str, str, str, str]] = []
    loc = metrics.get("localise")
    if loc:
        for scene, m in loc.items():
            ours = f"{_m(m.get('error_median_m'))} / {_m(m.get('error_p90_m'))}"
            base = m.get("paper_chain") or {}
            paper_chain = (f"paper's chain (range bins, SNR-weighted centroid) "
                           f"{_m(base.get('error_median_m'))} / {_m(base.get('error_p90_m'))}"
                           if base else "")
            rows.append((f"Localisation error median / p90, {scene}", "not reported", ours,
                         paper_chain, command("localise")))
        for scene, m in loc.items():
            if m.get("n_points_zero_doppler") is not None and m.get("paper_chain"):
                rows.append((f"Frames with a point, {scene}", "not reported",
                             f"{m['n_points']} of {m['n_frames']} ({m['n_points_zero_doppler']} "
                             "at zero Doppler, bridged)",
                             f"paper's chain {m['paper_chain']['n_points']} of {m['n_frames']}",
                             command("localise")))
        for scene, m in loc.items():
            if m.get("n_hidden_frames"):
                rows.append((f"Points while hidden behind the car, {scene}", "almost none (Fig. 7)",
                             f"{m['n_points_while_hidden']} of {m['n_hidden_frames']} hidden frames", "",
                             command("localise")))
    else:
        rows.append(("Localisation error", "not reported", "not run yet", "", command("localise")))

    train = metrics.get("train")
    if train:
        rows.append(("One-step validation RMSE (Table 1)", f"{VAL_RMSE.value} (units not stated)",
                     f"LSTM {_m(_get(train, 'lstm', 'val', 'rmse_m'), 4)}",
                     _baselines(train, "lstm", ("val", "rmse_m"), 4), command("train")))
        rows.append(("One-step test RMSE", "not reported", f"LSTM {_m(_get(train, 'lstm', 'test', 'rmse_m'), 4)}",
                     _baselines(train, "lstm", ("test", "rmse_m"), 4), command("train")))
    else:
        rows.append(("One-step validation RMSE (Table 1)", f"{VAL_RMSE.value}", "not run yet", "", command("train")))

    interp = metrics.get("interpolate")
    if interp:
        ours = "forward" if "forward" in interp else next(iter(interp))
        rows.append(("Interpolation error on hidden frames (mean of car scenes), three paper walks",
                     "no number (Fig. 8 only)",
                     f"{method_label(ours)} {_m(_get(interp, ours, 'all_scenes', 'hidden_mean_m'))}",
                     _baselines(interp, ours, ("all_scenes", "hidden_mean_m")), command("interpolate")))
    else:
        rows.append(("Interpolation error on hidden frames", "no number", "not run yet", "",
                     command("interpolate")))

    ev = metrics.get("evaluate")
    methods = _methods(ev)
    if ev and "lstm" in methods:
        spec = [
            ("Paper's metric, mean over the prediction (vs simulated truth), three paper walks",
             f"{PATH_ERROR_MEAN_M.value} m", "path_error_mean_m"),
            ("Paper's metric vs radar track of the walk without the car (what the paper measured)",
             f"{PATH_ERROR_MEAN_M.value} m", "path_error_radar_mean_m"),
            ("Paper's metric at the first step, three paper walks", f"< {PATH_ERROR_FIRST_BELOW_M.value} m",
             "path_error_first_m"),
            ("ADE over the whole horizon, three paper walks", "not reported", "ade_m"),
            ("FDE over the whole horizon, three paper walks", "not reported", "fde_m"),
        ]
        horizons = sorted({k.split("_", 1)[1] for k in ev["lstm"] if k.startswith("ade_") and k != "ade_m"},
                          key=lambda h: float(h.rstrip("s")))
        spec += [(f"ADE / FDE up to {h[:-1]} s, three paper walks", "not reported", (f"ade_{h}", f"fde_{h}"))
                 for h in horizons]
        for quantity, paper, key in spec:
            if isinstance(key, tuple):
                ours = f"{_m(ev['lstm'].get(key[0]))} / {_m(ev['lstm'].get(key[1]))}"
                base = "; ".join(f"{method_label(m)} {_m(ev[m].get(key[0]))} / {_m(ev[m].get(key[1]))}"
                                 for m in methods if m != "lstm")
            else:
                ours = _m(ev["lstm"].get(key))
                base = "; ".join(f"{method_label(m)} {_m(ev[m].get(key))}" for m in methods if m != "lstm")
            rows.append((quantity, paper, f"LSTM {ours}", base, command("evaluate")))
    else:
        rows.append(("Paper's metric (mean Euclidean error of the prediction)", f"{PATH_ERROR_MEAN_M.value} m",
                     "not run yet", "",
                     command("evaluate")))

    rows += benchmark_rows(metrics.get("benchmark"))
    rows += direct_rows(metrics.get("train_direct"))
    rows += calibration_rows(metrics.get("calibration"), (metrics.get("ethucy") or {}).get("best"))

    eth = metrics.get("ethucy")
    published = f"CVM {ETHUCY_CVM['ade']} / {ETHUCY_CVM['fde']} m (published)"
    if eth:
        def avg(model: str) -> str:
            a = _get(eth, model, "avg")
            return "n/a" if not a else f"{a['ade']:.2f} / {a['fde']:.2f} m"

        # model rows hold "avg"; "seeds" and "best_of_<n>" are blocks about them (issue 43)
        models = [m for m in eth if isinstance(eth[m], dict) and "avg" in eth[m]]
        best = ethucy_lead(eth)
        base = "; ".join([f"{ethucy_label(m)} {avg(m)}" for m in models if m != best]
                         + [f"{ethucy_label(m)} best-of-{k.removeprefix('best_of_')} "
                            f"{r['avg']['ade']:.2f} / {r['avg']['fde']:.2f} m"
                            for k, block in eth.items() if k.startswith("best_of_")
                            and isinstance(block, dict) for m, r in block.items()])
        sd = (eth.get("seeds") or {}).get(best)
        ours = (f"{ethucy_label(best)} {avg(best)}"
                + (" (best on val)" if best == eth.get("best") else "")
                + (f", mean of {sd['n']} seeds (sd {sd['ade_sd']:.3f} / {sd['fde_sd']:.3f} m)"
                   if sd else "")) if best else "n/a"
        rows.append(("ETH/UCY average ADE / FDE (observe 8, predict 12)", published, ours, base,
                     command("ethucy")))
    else:
        rows.append(("ETH/UCY average ADE / FDE (observe 8, predict 12)", published,
                     "not run yet (reports/metrics/ethucy.json absent)", "", command("ethucy")))
    return rows


def _ci(entry: Mapping[str, Any] | None, digits: int = 3) -> str:
    """``mean [lo, hi] m`` of a benchmark entry ({"mean", "ci95"})."""
    if not entry or entry.get("mean") is None or not math.isfinite(entry["mean"]):
        return "n/a"
    lo, hi = entry["ci95"]
    return f"{entry['mean']:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}] m"


def benchmark_rows(bench: Metrics) -> list[tuple[str, str, str, str, str]]:
    """Summary rows of reports/metrics/benchmark.json: LSTM and baselines, mean [95 % interval]
    over the walks, for the paper's metric, its first point, ADE/FDE at each horizon and the
    interpolation error on hidden frames."""
    if not bench:
        return [("Many-walk benchmark of the paper's scene", "not in the paper", "not run yet", "",
                 command("walks"))]
    n = bench.get("n_walks")
    tag = f", {n}-walk benchmark (95 % interval)"
    preds, fills = benchmark_methods(bench)       # the seed-ensemble members have their own table
    ours = "lstm" if "lstm" in preds else (preds[0] if preds else None)
    rows = []
    if ours:
        keys = [("Paper's metric, mean over the prediction", f"{PATH_ERROR_MEAN_M.value} m",
                 "path_error_mean_m"),
                ("Paper's metric at the first step", f"< {PATH_ERROR_FIRST_BELOW_M.value} m",
                 "path_error_first_m")]
        keys += [(f"{k.split('_')[0].upper()} up to {k.split('_')[1][:-1]} s", "not reported", k)
                 for k in bench[ours] if k.split("_")[0] in ("ade", "fde") and k[-1] == "s"]
        for quantity, paper, key in keys:
            rows.append((quantity + tag, paper, f"{method_label(ours)} {_ci(bench[ours].get(key))}",
                         "; ".join(f"{method_label(m)} {_ci(bench[m].get(key))}"
                                   for m in preds if m != ours), command("walks")))
    if fills:
        rows.append(("Interpolation error on hidden frames" + tag, "no number (Fig. 8 only)",
                     "; ".join(f"{m[len('fill_'):]} {_ci(bench[m].get('hidden_mean_m'))}"
                               for m in fills), "", command("walks")))
    return rows


def direct_rows(direct: Metrics) -> list[tuple[str, str, str, str, str]]:
    """Summary rows of reports/metrics/train_direct.json: ADE / FDE of the direct multi-step LSTM
    over each scored horizon on the held-out radar paths, the paper's LSTM and constant
    velocity beside it on the same pairs."""
    if not direct:
        return [("ADE / FDE on held-out radar paths, direct LSTM", "not reported", "not run yet", "",
                 command("train_direct"))]
    dt = direct["frame_period_s"]
    others = [m for m in ("lstm", "constant_velocity") if m in direct]
    rows = []
    for k in direct["steps_frames"]:
        def cell(m: str) -> str:
            s = direct[m]["test"]
            return f"{_m(s[f'ade_{k}'])} / {_m(s[f'fde_{k}'])}"
        n = direct["lstm_direct"]["test"]["n_pairs"]
        rows.append((f"ADE / FDE up to {k * dt:g} s, held-out radar paths ({n} pairs)",
                     "not reported", f"{method_label('lstm_direct')} {cell('lstm_direct')}",
                     "; ".join(f"{method_label(m)} {cell(m)}" for m in others),
                     command("train_direct")))
    return rows


#: the data set of calibration.json that is the simulated radar paths; the others are ETH/UCY folds
SIM_PATHS = "sim_paths"
#: ETH/UCY's model keys (reports/metrics/ethucy.json, merged into calibration.json): there "lstm"
#: is the direct multi-step predictor with an LSTM encoder, not the paper's next-point LSTM, and
#: not the radar paths' direct LSTM (lstm_direct) either
_ETHUCY_LABELS = {"cvm": "CVM", "constant_velocity": "constant velocity", "kalman": "Kalman (CV)",
                  "lstm": "LSTM encoder", "gru": "GRU encoder", "mlp": "MLP encoder",
                  "transformer": "transformer encoder",
                  "mix": "multi-modal MLP encoder", "lstm_rollout": "next-point LSTM"}


def ethucy_label(model: str) -> str:
    """The page's name of an ETH/UCY model key: the direct predictor's keys by their encoder
    ("lstm" -> "LSTM encoder"; unknown: the key)."""
    return _ETHUCY_LABELS.get(model, model)


def ethucy_lead(eth: Metrics) -> str | None:
    """The ETH/UCY model the page puts first: the one val chose (ethucy.json's "best") when it
    has a row, else the LSTM encoder's, else None."""
    rows = [m for m in eth if isinstance(eth[m], Mapping) and "avg" in eth[m]]
    best = eth.get("best")
    return best if best in rows else ("lstm" if "lstm" in rows else None)


def calibration_rows(cal: Metrics, ethucy_best: str | None = None
                     ) -> list[tuple[str, str, str, str, str]]:
    """Summary rows of reports/metrics/calibration.json: coverage of the 50/90/95 % ellipses and
    NLL of each method's calibrated distribution on every data set there (test paths: sim_paths;
    ETH/UCY folds where merged). The "ours" cell is the LSTM's on sim_paths and, on an ETH/UCY
    fold, the model val chose there (``ethucy_best``, ethucy.json's "best"; else the LSTM
    encoder's)."""
    if not cal:
        return [("Coverage of the 50/90/95 % prediction ellipses", "not in the paper", "not run yet",
                 "", command("calibration"))]
    rows = []
    datasets = list(dict.fromkeys(d for per in cal.values() for d in per))
    for d in datasets:
        lead = "lstm" if d == SIM_PATHS or ethucy_best not in cal else ethucy_best
        order = sorted(cal, key=lambda m: m != lead)        # "ours" first, as in the rows above
        label = method_label if d == SIM_PATHS else ethucy_label
        cells = [f"{label(m)} {cal[m][d]['coverage_50']:.3f} / "
                 f"{cal[m][d]['coverage_90']:.3f} / {cal[m][d]['coverage_95']:.3f}, "
                 f"NLL {cal[m][d]['nll']:.2f}" for m in order if d in cal[m]]
        rows.append((f"Coverage of the 50/90/95 % ellipses and NLL (nats), {d}",
                     "not in the paper (nominal 0.50 / 0.90 / 0.95)", cells[0] if cells else "n/a",
                     "; ".join(cells[1:]), command("calibration")))
    return rows


def differences(metrics: Mapping[str, Metrics]) -> list[str]:
    """Plain statements of where our results differ from the paper's, from the metrics themselves."""
    out = [
        "The paper's Figs. 6-10 come from a real MMWCAS recording of the scene; no such recording is "
        "available, so ours come from simulated scenes of the same geometry (radar, parked car, "
        "pedestrian walking out and turning +45, -45 or 0 degrees). The real recordings we do have "
        "(other radars and scenes) only go through the detection chain.",
    ]
    train = metrics.get("train")
    rmse = _get(train, "lstm", "val", "rmse_m")
    if rmse is not None:
        rel = "below" if rmse < VAL_RMSE.value else "above"
        out.append(f"One-step validation RMSE: ours {rmse:.4f} m is {rel} the paper's "
                   f"{VAL_RMSE.value} (whose units the paper does not state; we read metres, RMSE "
                   "over both coordinates).")
    ev = metrics.get("evaluate")
    methods = _methods(ev)
    if ev and "lstm" in methods:
        pe = ev["lstm"].get("path_error_mean_m")
        pr = ev["lstm"].get("path_error_radar_mean_m")
        if pe is not None:
            ratio = pe / PATH_ERROR_MEAN_M.value
            out.append(
                f"The paper's metric for the LSTM is {pe:.2f} m against the simulated truth"
                + (f" and {pr:.2f} m against the radar track without the car" if pr is not None else "")
                + f", {ratio:.1f}x the paper's {PATH_ERROR_MEAN_M.value} m. The paper reports one real walk per direction; "
                "its prediction length is not stated (ours: the rest of the scene)."
            )
        first = ev["lstm"].get("path_error_first_m")
        if first is not None:
            verdict = "meets" if first < PATH_ERROR_FIRST_BELOW_M.value else "misses"
            out.append(f"First predicted point: {first:.3f} m from the actual path, which {verdict} the "
                       f"paper's < {PATH_ERROR_FIRST_BELOW_M.value} m.")
        for key, what in (("path_error_mean_m", "the paper's metric"), ("ade_m", "ADE")):
            lstm = ev["lstm"].get(key)
            better = [m for m in methods if m != "lstm" and ev[m].get(key) is not None
                      and lstm is not None and ev[m][key] < lstm]
            if better:
                out.append(f"On {what}, {', '.join(method_label(m) for m in better)} beat"
                           f"{'s' if len(better) == 1 else ''} the LSTM "
                           f"({', '.join(f'{ev[m][key]:.2f} m' for m in better)} vs {lstm:.2f} m).")
            elif lstm is not None:
                out.append(f"On {what} the LSTM beats every baseline.")
    interp = metrics.get("interpolate")
    if interp and "forward" in interp:
        fwd = _get(interp, "forward", "all_scenes", "hidden_mean_m")
        better = {m: _get(interp, m, "all_scenes", "hidden_mean_m") for m in interp if m != "forward"}
        better = {m: v for m, v in better.items() if v is not None and fwd is not None and v < fwd}
        if better:
            out.append("Interpolation: the paper's forward LSTM rollout cannot use the reappearance "
                       f"point and errs {fwd:.2f} m on average on the hidden frames; "
                       + ", ".join(f"{method_label(m)} {v:.2f} m" for m, v in better.items())
                       + (" do better." if len(better) > 1 else " does better."))
    eth = metrics.get("ethucy")
    ours = ethucy_lead(eth) if eth else None
    if ours and "cvm" in eth:
        la, ca = _get(eth, ours, "avg"), _get(eth, "cvm", "avg")
        if la and ca:
            name = ethucy_label(ours) + (" (best on val)" if ours == eth.get("best") else "")
            wins = [k.upper() for k in ("ade", "fde") if la[k] < ca[k]]
            losses = [k.upper() for k in ("ade", "fde") if la[k] >= ca[k]]
            msg = (f"ETH/UCY: {name} {la['ade']:.2f} / {la['fde']:.2f} m vs CVM {ca['ade']:.2f} / "
                   f"{ca['fde']:.2f} m (published CVM {ETHUCY_CVM['ade']} / {ETHUCY_CVM['fde']} m); ")
            msg += ("it beats CVM on both." if not losses else
                    f"the {name} does not beat CVM on {' and '.join(losses)}"
                    + (f" (it does on {' and '.join(wins)})." if wins else "."))
            out.append(msg)
    elif not eth:
        out.append("The ETH/UCY benchmark has not been run yet (reports/metrics/ethucy.json is absent).")
    return out


def build_page(metrics: Mapping[str, Metrics], tables: Mapping[str, str | None],
               figures: Sequence[FigureEntry] = FIGURES,
               extra_figures: Sequence[FigureEntry] = ()) -> str:
    """The Markdown of reports/README.md.

    Args:
        metrics: parsed metrics JSON by name (localise, train, interpolate, evaluate, ethucy,
            benchmark, calibration); ``None`` or absent for files that do not exist.
        tables: Markdown of table1, table2 and benchmark by stage name (``None`` if not built).
        figures: the paper's figures to show, in order.
        extra_figures: more figures (e.g. the real recordings), shown after the paper's.
    """
    lines = [
        "# blindspot: reproduction report",
        "",
        "Every number, figure and table below is a pipeline output: `dvc repro` regenerates all of "
        "them; `dvc repro <stage>` or `python -m blindspot <stage>` one of them. This page is "
        f"written by the `report` stage ({command('report')}).",
        "",
        "## Our numbers beside the paper's",
        "",
        "Each row's last column is the DVC stage that recomputes it (outside DVC: "
        "`python -m blindspot <stage> key=value ...`).",
        "",
        markdown_table(("quantity", "paper", "ours", "baselines", "regenerate"),
                       [(*r[:4], r[4].split(" or ")[0]) for r in summary_rows(metrics)]),
        "## Where we differ from the paper",
        "",
        *[f"- {d}" for d in differences(metrics)],
        "",
        "## Figures",
        "",
    ]
    for f in (*figures, *extra_figures):
        lines += [f"### {f.title}", "", f"![{f.title}]({f.path})", "", f"{f.caption} Regenerate: "
                  f"{command(f.stage)}.", ""]
    if tables.get("benchmark"):
        lines += ["## Many-walk benchmark of the paper's scene", "",
                  "Randomised occluded walks (car pose and size, speed 1.0-1.5 m/s, turn -60..60 "
                  "deg, where the walk turns and when the prediction starts; "
                  "conf/walks/scene_walks.yaml) through the paths stage's radar chain, "
                  "then the interpolate and predict stages' code. Mean over walks with the 95 % "
                  "percentile-bootstrap interval; paired differences are the bootstrap of "
                  "per-walk differences. The three paper walks (Figs. 8-10) are one draw of this "
                  "kind: their numbers above are not an estimate of these means.", "",
                  "![many-walk benchmark](figures/benchmark.png)", "",
                  tables["benchmark"].strip(), "", f"Regenerate: {command('benchmark')}.", ""]
    lines += ["## Tables", ""]
    for stage, title in TABLE_STAGES.items():
        text = tables.get(stage)
        body = text.strip() if text else f"## {title}\n\nnot built yet"
        lines += [body.replace("## ", "### ", 1), "", f"Regenerate: {command(stage)}.", ""]
    return "\n".join(lines).rstrip() + "\n"
