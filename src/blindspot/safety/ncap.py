"""Euro NCAP 2026 crash-avoidance scoring of a pedestrian test cell by its impact speed.

Colour bands and cell scores by ego speed and relative impact speed v_imp (km/h), from the
Euro NCAP 2026 rating code (Euro-NCAP/euroncap_rating_2026 @ 94b1035, crash_avoidance/,
as tabulated in ../shared/scenarios/EURO_NCAP_PEDESTRIAN.md, "Scoring 2026 [R]"):

=============  =====  ======  ======  ======  =====
ego speed      green  yellow  orange  brown   red
=============  =====  ======  ======  ======  =====
10, 20 km/h    0      -       -       -       > 0
30 km/h        0      -       -       <= 10   > 10
40 km/h        0      -       <= 10   <= 20   > 20
50, 60 km/h    0      <= 10   <= 20   <= 30   > 30
=============  =====  ======  ======  ======  =====

Scores: green 1.0, yellow 0.75, orange 0.5, brown 0.25, red 0.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BANDS", "BAND_SCORES", "ncap_band"]

BANDS = ("green", "yellow", "orange", "brown", "red")
BAND_SCORES = {"green": 1.0, "yellow": 0.75, "orange": 0.5, "brown": 0.25, "red": 0.0}
# upper impact-speed limits (km/h) of yellow, orange, brown per ego speed; NaN = band not used
_LIMITS = {10: (np.nan, np.nan, np.nan), 20: (np.nan, np.nan, np.nan),
           30: (np.nan, np.nan, 10.0), 40: (np.nan, 10.0, 20.0),
           50: (10.0, 20.0, 30.0), 60: (10.0, 20.0, 30.0)}


def ncap_band(ego_speed_kmh, impact_speed_kmh) -> tuple[np.ndarray, np.ndarray]:
    """Band names (object array) and scores (float array) of impact speeds (...) km/h (0 or
    NaN = avoided) at ego speeds (...) km/h (broadcast). Raises ValueError for an ego speed off
    the 2026 grid (10, 20, ..., 60 km/h, +-0.5) or a negative impact speed."""
    ego, imp = np.broadcast_arrays(np.asarray(ego_speed_kmh, float),
                                   np.nan_to_num(np.asarray(impact_speed_kmh, float), nan=0.0))
    grid = np.round(ego / 10.0) * 10.0
    if np.any(np.abs(ego - grid) > 0.5) or not np.isin(grid, list(_LIMITS)).all():
        raise ValueError(f"ncap_band: ego speeds must be on the Euro NCAP 2026 grid "
                         f"10..60 km/h in 10 km/h steps, found {np.unique(ego).tolist()}")
    if np.any(imp < 0):
        raise ValueError("ncap_band: impact speeds must be >= 0 km/h")
    lim = np.array([_LIMITS[int(g)] for g in grid.ravel()]).reshape(grid.shape + (3,))
    with np.errstate(invalid="ignore"):
        within = imp[..., None] <= lim                         # NaN limits compare False
    idx = np.where(imp <= 0, 0, np.where(within.any(-1), 1 + np.argmax(within, -1), 4))
    names = np.asarray(BANDS, dtype=object)[idx]
    scores = np.array([BAND_SCORES[b] for b in BANDS])[idx]
    return names, scores
