"""The online ellipses a config group chooses among: its candidate settings
(:class:`blindspot.traj.config.OnlineCandidatesConfig`: sliding-window ACI,
:class:`blindspot.traj.conformal.AdaptiveConformal`, and scale tracking,
:class:`blindspot.traj.scale_tracker.ScaleTracker`), and a chosen setting rebuilt from what
the metrics files record of it."""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

from blindspot.traj.config import OnlineCandidatesConfig
from blindspot.traj.conformal import AdaptiveConformal, ConformalError, OnlineEllipses
from blindspot.traj.scale_tracker import ScaleTracker

__all__ = ["ONLINE_METHODS", "online_candidates", "online_from_setting"]

# what each method's ``setting`` records, beside ``online_method``: the constructor's arguments
_ARGUMENTS = {"aci_window": ("online_gamma", "online_window", "online_rescale_after"),
              "scale_tracker": ("online_eta", "online_kappa", "online_prior_outcomes")}
#: the kinds of online ellipses a recorded setting may name
ONLINE_METHODS = tuple(_ARGUMENTS)


def online_candidates(config: OnlineCandidatesConfig, levels: tuple[float, ...]
                      ) -> tuple[OnlineEllipses, ...]:
    """Every candidate of ``config`` at ``levels``: the sliding-window ellipses of each
    (gamma, window, rescale) combination, then the scale trackers of each (eta, kappa), in the
    config's order (a tie in the choice goes to the first).

    Raises:
        ConformalError: ``config`` not an :class:`OnlineCandidatesConfig`, or the settings'
            own errors.
    """
    if not isinstance(config, OnlineCandidatesConfig):
        raise ConformalError(f"online_candidates: config: expected an OnlineCandidatesConfig "
                             f"(the ethucy or calibration group), found {type(config).__name__}")
    levels = tuple(levels)
    return (*(AdaptiveConformal(levels, g, w, k) for g, w, k in itertools.product(
                config.online_gammas, config.online_windows, config.online_rescales)),
            *(ScaleTracker(levels, e, k) for e, k in itertools.product(
                config.online_etas, config.online_kappas)))


def online_from_setting(setting: Mapping[str, Any], levels: tuple[float, ...],
                        where: str = "setting") -> OnlineEllipses:
    """The online ellipses whose ``setting`` (:attr:`OnlineEllipses.setting`: ``online_method``
    and its ``online_<argument>`` keys, as the calibration stage's online.json records each
    predictor's choice) is ``setting``, at ``levels``.

    Raises:
        ConformalError: naming ``where``: not a mapping, an unknown method, a missing or
            unknown key, or the setting's own errors.
    """
    if not isinstance(setting, Mapping):
        raise ConformalError(f"{where}: expected a mapping with online_method, found "
                             f"{type(setting).__name__}")
    method = setting.get("online_method")
    if method not in _ARGUMENTS:
        raise ConformalError(f"{where}: online_method: expected one of {ONLINE_METHODS}, found "
                             f"{method!r}")
    keys = _ARGUMENTS[method]
    if set(setting) != {"online_method", *keys}:
        raise ConformalError(f"{where}: expected the keys {['online_method', *keys]} of "
                             f"{method}, found {sorted(setting)}")
    for k in keys:
        v = setting[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConformalError(f"{where}: {k}: expected a number, found {v!r}")
    cls = AdaptiveConformal if method == "aci_window" else ScaleTracker
    try:
        return cls(tuple(levels), *(setting[k] for k in keys))
    except ConformalError as e:
        raise ConformalError(f"{where}: {e}") from None
