"""The online ellipses a config names (``calibration.online_method``): scale tracking
(:class:`blindspot.traj.scale_tracker.ScaleTracker`) or sliding-window ACI
(:class:`blindspot.traj.conformal.AdaptiveConformal`), with the group's settings."""

from __future__ import annotations

from blindspot.traj.config import ONLINE_METHODS, CalibrationConfig
from blindspot.traj.conformal import AdaptiveConformal, ConformalError, OnlineEllipses
from blindspot.traj.scale_tracker import ScaleTracker

__all__ = ["online_ellipses"]


def online_ellipses(c: CalibrationConfig, levels: tuple[float, ...]) -> OnlineEllipses:
    """The online ellipses of ``c.online_method`` at ``levels``: ``"scale_tracker"`` with
    ``online_eta`` / ``online_kappa``, ``"aci_window"`` with ``online_gamma`` /
    ``online_window`` / ``online_rescale_after``.

    Raises:
        ConformalError: ``c`` not a :class:`CalibrationConfig`, an unknown method, or the
            settings' own errors.
    """
    if not isinstance(c, CalibrationConfig):
        raise ConformalError(f"online_ellipses: c: expected a CalibrationConfig, found "
                             f"{type(c).__name__}")
    if c.online_method == "scale_tracker":
        return ScaleTracker(tuple(levels), c.online_eta, c.online_kappa)
    if c.online_method == "aci_window":
        return AdaptiveConformal(tuple(levels), c.online_gamma, c.online_window,
                                 c.online_rescale_after)
    raise ConformalError(f"calibration.online_method: expected one of {ONLINE_METHODS}, found "
                         f"{c.online_method!r}")
