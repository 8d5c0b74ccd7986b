"""Score interpolation and prediction on many measured walks of the paper's scene.

The same library calls as the ``interpolate`` and ``predict`` stages, batched over walks:
:func:`blindspot.traj.interpolation.fill_gaps` fills each walk's track (measured up to its
prediction start) with every interpolation method, scored on the hidden frames
(:func:`blindspot.traj.bootstrap.hidden_gap_error`, as ``score_interpolation``);
:func:`blindspot.traj.forecast.forecast_tracks` predicts from the track filled by
``prediction_input`` (what ``forecast_track`` with that fill computes), scored against the
truth (:func:`blindspot.traj.bootstrap.prediction_scores`, as ``score_prediction``).
Predictors that give a distribution (``predict_distribution``) are also scored on ellipse
coverage and NLL (:mod:`blindspot.traj.distribution`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from blindspot.synth.scene_walks import SceneWalks
from blindspot.traj.bootstrap import hidden_gap_error, prediction_scores
from blindspot.traj.forecast import forecast_distributions, forecast_tracks
from blindspot.traj.interpolation import fill_gaps

__all__ = ["COVERAGE_LEVELS", "score_scene_walks", "future_truth", "online_by_predictor"]

COVERAGE_LEVELS = (0.5, 0.9, 0.95)


def future_truth(walks: SceneWalks, horizon: int) -> np.ndarray:
    """(N, horizon, 2) true positions at frames start .. start + horizon - 1 of each walk."""
    idx = walks.start[:, None] + np.arange(horizon)[None, :]
    return np.take_along_axis(walks.truth, idx[..., None], axis=1)


def score_scene_walks(walks: SceneWalks, measured: np.ndarray, *,
                      predictors: Mapping[str, object], interpolation_methods: tuple[str, ...],
                      prediction_input: str, gap_predictor,
                      smoother: Callable[[np.ndarray], np.ndarray], horizon: int, dt_s: float,
                      horizons_s: tuple[float, ...],
                      distributions: Mapping[str, object] | None = None, threads: int = 1,
                      online: Mapping[str, object] | None = None,
                      priors: Mapping[str, np.ndarray] | None = None,
                      ) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, np.ndarray]]:
    """Per-walk scores of every interpolation and prediction method.

    Args:
        walks: the drawn walks (truth, hidden frames, prediction starts).
        measured: (N, T, 2) radar points, NaN where none and from each walk's start on.
        predictors: {name: PathPredictor} (``blindspot.traj.baselines.prediction_methods``).
        interpolation_methods: ``eval.interpolation_methods``; ``prediction_input`` the one the
            predictions start from (``eval.prediction_input``).
        gap_predictor: the predictor the forward/bidirectional fills roll out (the LSTM).
        smoother: batched smoother for the kalman fill, (N, T, 2) -> (N, T, 2).
        horizon: frames predicted. dt_s: frame period. horizons_s: ADE/FDE horizons.
        distributions: {name: predictor with ``predict_distribution``} for the methods that
            give a Gaussian forecast (scored on the same histories as their point prediction).
        threads: torch threads while scoring (restored after).
        online, priors: {name: online ellipses} (each predictor's setting, chosen by the
            calibration stage: :class:`blindspot.traj.scale_tracker.ScaleTracker` or
            :class:`blindspot.traj.conformal.AdaptiveConformal`) scored beside each
            distribution with both, ``priors[name]`` (M, H_cal) its scores on the
            validation pairs (the calibration stage's ``val_scores.npz``): the walks are met one
            after another in their drawn order, each walk's ellipses from the outcomes of the
            walks before it (:func:`distribution_scores`).

    Returns:
        ``(scores, predictions)``: scores {method or ``fill_<method>``: {metric: (N,)}};
        predictions {method: (N, horizon, 2)} (for figures).
    """
    import torch

    if online is not None:
        _check_online(online, priors or {}, "score_scene_walks")
    previous = torch.get_num_threads()
    torch.set_num_threads(int(threads))
    try:
        return _score(walks, measured, predictors, interpolation_methods, prediction_input,
                      gap_predictor, smoother, horizon, dt_s, horizons_s, distributions,
                      online or {}, priors or {})
    finally:
        torch.set_num_threads(previous)


def _score(walks, measured, predictors, interpolation_methods, prediction_input, gap_predictor,
           smoother, horizon, dt_s, horizons_s, distributions, online, priors):
    observed = np.isfinite(measured).all(axis=-1)
    scores: dict[str, dict[str, np.ndarray]] = {}
    filled = {}
    methods = tuple(dict.fromkeys((*interpolation_methods, prediction_input)))
    for m in methods:
        filled[m] = fill_gaps(measured, m, predictor=gap_predictor, smoother=smoother)
        if m in interpolation_methods:
            scores[f"fill_{m}"] = {"hidden_mean_m": hidden_gap_error(
                filled[m], walks.truth, observed, walks.hidden)}
    truth = future_truth(walks, horizon)
    end = walks.start + horizon
    predictions = {}
    for name, predictor in predictors.items():
        pred = forecast_tracks(filled[prediction_input], walks.start, predictor, end=end)
        predictions[name] = pred
        scores[name] = prediction_scores(pred, truth, dt_s, horizons_s)
        if distributions and name in distributions:
            scores[name].update(distribution_scores(
                distributions[name], filled[prediction_input], walks.start, end, truth,
                online=online.get(name) if name in priors else None,
                prior=priors.get(name)))
    return scores, predictions


def distribution_scores(predictor, tracks: np.ndarray, start: np.ndarray, end: np.ndarray,
                        truth: np.ndarray, *, online=None, prior: np.ndarray | None = None
                        ) -> dict[str, np.ndarray]:
    """Per-walk share of the true future points (N, H, 2) inside the 50/90/95 % ellipses, and
    the mean NLL (nats per point), of a predictor's Gaussian forecast from the same histories
    as its point prediction (:func:`blindspot.traj.forecast.forecast_distributions`).

    A predictor calibrated for ``predictor.horizon`` steps (``ScaledPredictor``) scores only
    the walks whose forecast, counted from the last point seen (missed frames just before the
    start add steps), stays within it; the others get NaN.

    With ``online`` (online ellipses of the same levels,
    :class:`~blindspot.traj.conformal.OnlineEllipses`) and ``prior`` (M, S) (the predictor's scores on its validation pairs, S forecast
    steps from the last point seen), also ``online_coverage_<p>`` per walk: the share of its
    points inside the online ellipses, each point scored with the others of its
    forecast step (step lead + j for the walk's point j), the walks one stream in their order
    (walk k's outcome known before walk k + 1 is predicted)."""
    from blindspot.traj.distribution import chi2_2dof_radius_sq, mahalanobis_sq

    n = len(start)
    lead = lead_of(tracks, start)                                          # (N,)
    steps = lead + (end - start)
    ok = steps <= getattr(predictor, "horizon", np.inf)
    keys = [f"coverage_{round(level * 100)}" for level in COVERAGE_LEVELS] + ["nll"]
    if online is not None:
        keys += [f"online_coverage_{round(level * 100)}" for level in COVERAGE_LEVELS]
    out = {k: np.full(n, np.nan) for k in keys}
    if not ok.any():
        return out
    fc = forecast_distributions(tracks[ok], start[ok], predictor, end=end[ok])
    d2 = mahalanobis_sq(fc, truth[ok])                                     # (n_ok, H)
    levels = np.asarray(COVERAGE_LEVELS)
    if getattr(predictor, "mixture", None) is not None:
        # a mixture-calibrated predictor (ScaledPredictor with a ScaleMixture) has its own
        # radius per forecast step; walk b's point j is step lead_b + j from the last point seen
        n_steps = int(steps[ok].max())
        idx = np.clip(lead[ok][:, None] + np.arange(fc.horizon)[None, :], 0, n_steps - 1)
        r2 = predictor.radius_sq(levels, n_steps)[:, idx]                  # (L, n_ok, H)
    else:
        r2 = np.broadcast_to(chi2_2dof_radius_sq(levels)[:, None, None], (levels.size,) + d2.shape)
    for i, key in enumerate(keys[:len(COVERAGE_LEVELS)]):
        out[key][ok] = np.nanmean(d2 <= r2[i], axis=1)
    c = fc.cov
    logdet = np.log(c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] ** 2)
    out["nll"][ok] = np.nanmean(0.5 * d2 + 0.5 * logdet + np.log(2 * np.pi), axis=1)
    if online is not None:
        for key, share in _online_shares(online, prior, d2, lead[ok]).items():
            out[key][ok] = share
    return out


def lead_of(tracks: np.ndarray, start: np.ndarray) -> np.ndarray:
    """(N,) missed frames between each track's last point seen and its prediction start."""
    return start - _last_seen_before(tracks, start) - 1


def _online_shares(online, prior: np.ndarray, d2: np.ndarray, lead: np.ndarray
                   ) -> dict[str, np.ndarray]:
    """Per-walk share of points (d2 (n, H), NaN after a walk's horizon) inside the online
    ellipses; point j of walk b is forecast step lead[b] + j of ``prior``'s S."""
    n, h = d2.shape
    steps = prior.shape[1]
    col = lead[:, None] + np.arange(h)[None, :]                             # (n, H)
    scores = np.full((n, steps), np.nan)
    keep = (col < steps) & np.isfinite(d2)
    scores[np.nonzero(keep)[0], col[keep]] = d2[keep]
    t = np.arange(n, dtype=float)
    radii = online.radii(scores, t, t + 0.5, np.zeros(n, np.int64), prior)  # (L, n, S)
    seen = ~np.isnan(scores)
    inside = (scores[None] <= radii) & seen[None]
    per_walk = inside.sum(axis=2) / np.maximum(seen.sum(axis=1), 1)[None]   # (L, n)
    per_walk = np.where(seen.any(axis=1)[None], per_walk, np.nan)
    return {f"online_coverage_{round(100 * lv)}": per_walk[i]
            for i, lv in enumerate(online.levels)}


def _last_seen_before(tracks: np.ndarray, start: np.ndarray) -> np.ndarray:
    seen = np.isfinite(tracks).all(axis=-1) & (np.arange(tracks.shape[1])[None, :]
                                                < start[:, None])
    return tracks.shape[1] - 1 - np.argmax(seen[:, ::-1], axis=1)


# ----------------------------------------------------------------------------- the walks stage's
def walk_statistics(scores: Mapping[str, Mapping[str, np.ndarray]], names: list[str],
                    members: Mapping[str, object], interpolation_methods, *, n_walks: int,
                    n_boot: int, level: float, seed: int, train_seed: int):
    """(metrics, extra, fills): every method's mean over walks with its bootstrap interval
    (benchmark.json's shape, ``{"n_walks": N, method: {metric: {mean, ci95}}}``), and what does
    not fit it: the paired differences between methods (``names``) and between fills, and the
    spread of the ensemble's members (``members``, seeds from ``train_seed``)."""
    from blindspot.traj.bootstrap import bootstrap_means, paired_differences

    boot = dict(n_boot=n_boot, level=level, seed=seed)
    pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    fills = [f"fill_{m}" for m in interpolation_methods]
    pairs += [(a, b) for i, a in enumerate(fills) for b in fills[i + 1:]]
    metrics = {"n_walks": n_walks, **bootstrap_means(scores, **boot)}
    extra: dict = {"paired": paired_differences(scores, pairs, **boot)}
    if members:
        spread = {k: [metrics[m][k]["mean"] for m in members]
                  for k in ("path_error_mean_m", "ade_1s", "ade_2s", "fde_2s")}
        extra["lstm_members"] = {"n_members": len(members), "seeds_from": int(train_seed),
                                 **{k: {"min": min(v), "max": max(v)} for k, v in spread.items()}}
    return metrics, extra, fills


def per_walk_table(scores: Mapping[str, Mapping[str, np.ndarray]], walks: SceneWalks):
    """One row per walk: its index, speed, turn and every ``<method>.<metric>`` score."""
    import pandas as pd

    per_walk = pd.DataFrame({f"{m}.{k}": v for m, per in scores.items() for k, v in per.items()})
    per_walk.insert(0, "walk", range(len(walks)))
    per_walk.insert(1, "speed_mps", walks.speed_mps)
    per_walk.insert(2, "turn_deg", walks.turn_deg)
    return per_walk


def walk_lines(metrics: dict, names: list[str]) -> list[str]:
    """One log line per method: the paper's metric with its interval, ADE 1 s, FDE 2 s."""
    return [f"benchmark {name}: paper's metric {m['path_error_mean_m']['mean']:.3f} m "
            f"{m['path_error_mean_m']['ci95']}, ADE 1 s {m['ade_1s']['mean']:.3f} m, "
            f"FDE 2 s {m['fde_2s']['mean']:.3f} m"
            for name in names for m in [metrics[name]]]


def score_walks(walks: SceneWalks, measured: np.ndarray, *, ev, bench, dt: float,
                lstm, direct, records: dict, val_scores, online_settings: Mapping[str, Mapping],
                seed: int, train_seed: int):
    """The walks stage's scoring, ``(metrics, extra, scores, names, fills)``: the paper's
    methods (``ev.prediction_methods``), the direct LSTM ``direct`` (continued at its last
    step's velocity past its horizon) and each member of the LSTM's ensemble score the walks
    (:func:`score_scene_walks`) with the calibration stage's distributions (``records``,
    ``val_scores``) and the online ellipses of the setting it chose for each predictor
    (``online_settings``, its online.json: {name: setting}); then :func:`walk_statistics`;
    ``extra`` also names each predictor's online setting (``online_setting``)."""
    from blindspot.traj.baselines import kalman_baseline, prediction_methods
    from blindspot.traj.calibration import calibrated_distributions
    from blindspot.traj.direct import NAME as DIRECT
    from blindspot.traj.predictor import ConstantVelocityTail

    predictors = {**prediction_methods(ev, dt, lstm),
                  DIRECT: ConstantVelocityTail(direct, direct.cfg.horizon)}
    distributions, priors = calibrated_distributions(records, predictors, val_scores)
    online = online_by_predictor(online_settings, priors)
    members = ({f"lstm_member{i}": lstm.member(i) for i in range(lstm.n_members)}
               if lstm.n_members > 1 else {})
    scores, _ = score_scene_walks(
        walks, measured, predictors={**predictors, **members},
        interpolation_methods=ev.interpolation_methods, prediction_input=ev.prediction_input,
        gap_predictor=lstm, smoother=kalman_baseline(ev, dt).smooth_batch,
        horizon=bench.horizon_frames, dt_s=dt, horizons_s=ev.horizons_s,
        distributions=distributions, threads=bench.threads, online=online, priors=priors)
    names = list(predictors)
    metrics, extra, fills = walk_statistics(
        scores, names, members, ev.interpolation_methods, n_walks=len(walks),
        n_boot=bench.n_bootstrap, level=bench.ci_level, seed=seed, train_seed=train_seed)
    extra["online_setting"] = {n: o.setting for n, o in online.items()}
    return metrics, extra, scores, names, fills


def online_by_predictor(settings: Mapping[str, Mapping], priors: Mapping[str, np.ndarray]
                        ) -> dict[str, object]:
    """{name: online ellipses at :data:`COVERAGE_LEVELS`} of every predictor with a prior
    (``priors``: the calibration stage's val_scores.npz), rebuilt from ``settings`` (its
    online.json: {name: setting}, :func:`blindspot.traj.online.online_from_setting`).

    Raises:
        TypeError: ``settings`` not a mapping. ValueError: no setting for a predictor with a
            prior (its online columns would silently go missing). ConformalError: a malformed
            setting, named.
    """
    from blindspot.traj.online import online_from_setting

    if not isinstance(settings, Mapping):
        raise TypeError(f"online_by_predictor: settings: expected a mapping of predictor names "
                        f"to settings (online.json), found {type(settings).__name__}")
    online = {n: online_from_setting(settings[n], COVERAGE_LEVELS, where=f"online.json: {n}")
              for n in priors if n in settings}
    _check_online(online, priors, "online_by_predictor")
    return online


def _check_online(online, priors: Mapping[str, np.ndarray], who: str) -> None:
    """ValueError unless ``online`` maps every name of ``priors`` to online ellipses."""
    if not isinstance(online, Mapping):
        raise TypeError(f"{who}: online: expected a mapping of predictor names to online "
                        f"ellipses, found {type(online).__name__}")
    missing = sorted(set(priors) - set(online))
    if missing:
        raise ValueError(f"{who}: online (the calibration stage's online.json): expected a "
                         f"setting for every calibrated predictor, found none for {missing}")
