"""Markdown pages of the safety stage's metrics (issue 40): the Monte-Carlo grid page and the
Euro NCAP nominal grids with the held-out figures. Formatting only: every number is read from
the metrics the safety stages wrote (reports/metrics/safety.json, ncap.json,
safety_held_out_bound.json)."""

from __future__ import annotations

import pandas as pd

from blindspot.report.bound_steps import bound_steps, same_draw
from blindspot.report.safety_figures import ncap_grid_markdown

__all__ = ["predictor_names", "operating_inputs", "grid_page", "ncap_page", "held_out_ladder",
           "lstm_verdict"]


def predictor_names(metrics: dict) -> list[str]:
    """The predictors of safety.json, in its order: its entries with rates by input
    (``by_input``); the blocks of the draws and halves beside them have none."""
    return [p for p, m in metrics.items() if isinstance(m, dict) and "by_input" in m]


def operating_inputs(metrics: dict, bound: dict) -> tuple[dict, dict, tuple[int, int]]:
    """(per input the predictors' metrics, the bounds' avoided rates, (M, N) of the bounds'
    confirmation) of safety.json and safety_bound.json: what the operating-characteristic
    figure draws."""
    preds = predictor_names(metrics)
    inputs = metrics[preds[0]]["settings"]["inputs"]
    operating = {inp: {p: metrics[p]["by_input"][inp] for p in preds
                       if inp in metrics[p]["by_input"]} for inp in inputs}
    bounds = {k: v["avoided_rate"] for k, v in bound.items() if k != "settings"}
    return operating, bounds, (bound["settings"]["confirm_m"], bound["settings"]["confirm_n"])


def grid_page(grid: pd.DataFrame, metrics: dict) -> str:
    """The Monte-Carlo grid page (reports/tables/safety_grid.md): one Euro NCAP-shaped table
    per input and predictor (:func:`~blindspot.report.safety_figures.ncap_grid_markdown`)."""
    preds = predictor_names(metrics)
    settings = metrics[preds[0]]["settings"]
    md = [f"Euro NCAP-shaped grid of the Monte-Carlo intruding scenes ({settings['headline_input']}"
          " input; cells: scenes avoided / scenes, mean impact speed, 2026 band of that mean; and "
          "how many of them braked from a frame before anything, line of sight or a radar point, "
          "showed the lead pedestrian: for another pedestrian or clutter). The Euro NCAP "
          "nominal grids, one scene per cell, are in safety_ncap.md.\n"]
    for inp in settings["inputs"]:
        for p in preds:
            if inp in metrics[p]["by_input"]:
                md += [f"\n### {p} ({inp})\n\n", ncap_grid_markdown(grid[grid.input == inp], p)]
    return "".join(md)


def _fmt(x, nd=2) -> str:
    return "-" if x is None else f"{x:.{nd}f}"


def _rate_ci(block: dict, key: str, nd: int) -> str:
    """``0.52 [0.47, 0.58]``: ``block[key]`` with its ``key_ci95`` ("-" for a missing end)."""
    ci = block.get(f"{key}_ci95")
    return (f"{_fmt(block.get(key), nd)} [{_fmt(ci[0], nd) if ci else '-'}, "
            f"{_fmt(ci[1], nd) if ci else '-'}]")


def ncap_page(ncap: dict, metrics: dict, held_bound: dict | None = None) -> str:
    """reports/tables/safety_ncap.md: the held-out figures of the headline input per predictor
    (with their 95 % intervals), where the time goes on the held-out draw
    (:func:`held_out_ladder`, with ``held_bound``: safety_held_out_bound.json), the
    first-radar-point delays per speed, and the Euro NCAP nominal grids (impact speed km/h and
    2026 band per cell) per input and predictor."""
    held, tune = metrics.get("held_out", {}), metrics.get("tuning_half", {})
    draw = metrics.get("tuning_draw", {})
    out = ["# Safety: held-out figures and the Euro NCAP nominal grids\n\n",
           f"Held out: the independent draw of seed {held.get('seed')} (safety_held_out stage; "
           f"tracker input), {held.get('n_intruding')} intruding and "
           f"{held.get('n_non_intruding')} non-intruding scenes. The chain's settings were chosen "
           f"on the main draw's even half ({tune.get('n_intruding')} / "
           f"{tune.get('n_non_intruding')}); each predictor's AEB operating point (the threshold "
           f"that avoids most once the child is visible with false activations at most the "
           f"target) on the independent tuning draw of seed {draw.get('seed')} "
           f"({draw.get('n_intruding')} / {draw.get('n_non_intruding')}; safety_tuning stage). "
           f"Rates with Wilson 95 % intervals; *: no threshold kept to the target on the "
           f"tuning draw (the one with the fewest false activations there).\n\n",
           "| predictor | avoided after visible | false activations | at the tuning draw's "
           "operating point: threshold, avoided after visible, false activations | first point "
           "-> confirmed / moving / AEB, median s |\n|---|---|---|---|---|\n"]
    for p, h in held.items():
        if not isinstance(h, dict):
            continue
        op = h.get("at_tuning_operating_point")
        at = ("-" if not op else
              f"{op['aeb_threshold']:.6g}{'' if op.get('target_met_on_tuning', True) else '*'}, "
              f"{_rate_ci(op, 'avoided_after_visible_rate', 2)}, "
              f"{_rate_ci(op, 'false_activation_rate', 3)}")
        out.append(f"| {p} | {_rate_ci(h, 'avoided_after_visible_rate', 2)} | "
                   f"{_rate_ci(h, 'false_activation_rate', 3)} | {at} | "
                   f"{_fmt(h.get('first_point_to_confirmed_s_median'))} / "
                   f"{_fmt(h.get('first_point_to_moving_s_median'))} / "
                   f"{_fmt(h.get('first_point_to_aeb_s_median'))} |\n")
    out.append(lstm_verdict(held))
    if held_bound:
        first = metrics.get(next(iter(predictor_names(metrics)), ""), {})
        out.append(held_out_ladder(held_bound, held,
                                   (first.get("settings") or {}).get("aeb_threshold")))
    out.append("\n## First radar point of the lead pedestrian -> first confirmed track / moving "
               "track / AEB request (main Monte-Carlo draw, all intruding scenes, headline input; "
               "median / p90 s, never)\n\n")
    for p in predictor_names(metrics):
        m = metrics[p]
        steps = [(word, m[key]) for word, key in (("confirmed", "first_point_to_confirmed_s"),
                                                  ("moving", "first_point_to_moving_s"),
                                                  ("AEB", "first_point_to_aeb_s")) if key in m]
        if not steps:
            continue
        out.append(f"- {p}: " + "; ".join(
            f"{word} " + ", ".join(f"{k} km/h {_fmt(v['median'])} / {_fmt(v['p90'])}"
                                   for k, v in d["by_speed_kmh"].items())
            + f" (never {d['n_never']})" for word, d in steps) + "\n")
    out.append("\n## Euro NCAP nominal grids (one nominal scene per cell; impact speed km/h, "
               "2026 band)\n")
    for proto, by_input in ncap.items():
        for inp, by_pred in by_input.items():
            for p, by_speed in by_pred.items():
                pcts = sorted({pc for v in by_speed.values() for pc in v}, key=float)
                out.append(f"\n### {proto.upper()} ({inp}, {p})\n\n| km/h | "
                           + " | ".join(f"{pc} %" for pc in pcts) + " |\n|---|"
                           + "---|" * len(pcts) + "\n")
                for kmh in sorted(by_speed, key=float):
                    row = [by_speed[kmh].get(pc) for pc in pcts]
                    out.append(f"| {kmh} | " + " | ".join(
                        "-" if c is None else f"{c['impact_speed_kmh']:.1f} {c['band']}"
                        for c in row) + " |\n")
    return "".join(out)


def held_out_ladder(bound: dict, held: dict, aeb_threshold: float | None = None) -> str:
    """The section "Where the time goes, held out": per row, once the child is visible, the
    avoided rate (Wilson 95 %) and false activations, overall and per speed, of a perfect
    decision (braking at the best frame, never for a child who does not cross) from the first
    frame of each piece of information (``bound``: safety_held_out_bound.json,
    :func:`~blindspot.report.bound_steps.bound_steps`), then the chain's predictors on the same
    draw (``held``: safety.json's ``held_out``) at the configured AEB threshold
    (``aeb_threshold``, for its label) and at the tuning draw's operating point. "" when
    ``bound`` has none of the steps or is not of ``held``'s draw (its seed,
    :func:`~blindspot.report.bound_steps.same_draw`). A goal above a bound's interval is out of
    reach of every decision logic on these points."""
    steps = bound_steps(bound) if same_draw(bound, held) else []
    if not steps:
        return ""
    speeds = sorted({k for _, b in steps for k in b.get("by_speed_kmh", {})}, key=float)
    head = ("\n## Where the time goes, held out (the same draw; avoided after visible, false "
            "activations)\n\nA perfect decision brakes at the best frame from the first frame "
            "of the information about the lead child and never for a child who does not cross "
            "(safety_held_out_bound.json); the chain's rows are the predictors on their own "
            "tracks (first point -> confirmed / moving / AEB in the table above).\n\n"
            "| information, decision | avoided after visible | false activations | "
            + " | ".join(f"{k} km/h" for k in speeds) + " |\n|---|---|---|"
            + "---|" * len(speeds) + "\n")
    rows = []
    for words, b in steps:
        per = b.get("by_speed_kmh", {})
        rows.append(f"| perfect decision from {words} | "
                    f"{_rate_ci(b, 'avoided_after_visible_rate', 2)} | "
                    f"{_rate_ci(b, 'false_activation_rate', 3)} | "
                    + " | ".join(_fmt((per.get(k) or {}).get("avoided_after_visible_rate"))
                                 for k in speeds) + " |\n")
    at = "configured AEB threshold" + ("" if aeb_threshold is None else f" {aeb_threshold:g}")
    for p, h in held.items():
        if not isinstance(h, dict) or p == "none" or "avoided_after_visible_rate" not in h:
            continue
        per = h.get("avoided_after_visible_rate_by_speed_kmh") or {}
        rows.append(f"| the chain, {p}, {at} | {_rate_ci(h, 'avoided_after_visible_rate', 2)} | "
                    f"{_rate_ci(h, 'false_activation_rate', 3)} | "
                    + " | ".join(_fmt(per.get(k)) for k in speeds) + " |\n")
        op = h.get("at_tuning_operating_point")
        if op:
            rows.append(f"| the chain, {p}, tuning draw's threshold {op['aeb_threshold']:.6g} | "
                        f"{_rate_ci(op, 'avoided_after_visible_rate', 2)} | "
                        f"{_rate_ci(op, 'false_activation_rate', 3)} | "
                        + " | ".join("-" for _ in speeds) + " |\n")
    return head + "".join(rows)


def lstm_verdict(held: dict, learned: tuple[str, ...] = ("lstm", "lstm_direct"),
                 baselines: tuple[str, ...] = ("constant_velocity", "kalman")) -> str:
    """One paragraph: do the learned predictors earn their place against the baselines on the
    held-out block (``held``: predictor -> avoided_after_visible_rate(_ci95),
    false_activation_rate)? A learned predictor earns it when the lower end of its avoided
    interval is above the best baseline's avoided rate and its false activations are no
    higher; "" when the block lacks them."""
    have = [p for p in (*learned, *baselines) if isinstance(held.get(p), dict)]
    base = [p for p in baselines if p in have]
    if not base or not any(p in have for p in learned):
        return ""
    top = max(base, key=lambda p: held[p]["avoided_after_visible_rate"])
    a0, f0 = held[top]["avoided_after_visible_rate"], held[top]["false_activation_rate"]
    earns = [p for p in learned if p in have
             and (held[p].get("avoided_after_visible_rate_ci95") or [0.0])[0] > a0
             and held[p]["false_activation_rate"] <= f0]
    rows = ", ".join(f"{p} {_fmt(held[p]['avoided_after_visible_rate'])} at "
                     f"{_fmt(held[p]['false_activation_rate'], 3)}" for p in have)
    if earns:
        one = len(earns) == 1
        word = (f"{' and '.join(earns)} earn{'s' if one else ''} {'its' if one else 'their'} "
                f"place: the 95 % interval of {'its' if one else 'each'} avoided rate lies above "
                f"{top}'s, at no more false activations")
    else:
        word = (f"the LSTMs do not earn their place on these numbers: for none of them does the "
                f"95 % interval of the avoided rate lie above {top}'s at no more false "
                f"activations")
    return (f"\nLearned against baseline predictors, held out (avoided after visible at false "
            f"activations): {rows}; {word}.\n\n")
