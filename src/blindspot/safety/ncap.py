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

from dataclasses import replace

import numpy as np

__all__ = ["BANDS", "BAND_SCORES", "NCAP_PROTOCOLS", "ncap_band", "nominal_scenes",
           "nominal_cell"]

#: The Euro NCAP nominal grids scored one nominal scene per cell (issue 40): protocol ->
#: ((named scene of conf/scenario, impact point %), ...): CPNCO (child from behind the parked
#: cars) at 25 / 50 / 75 %, CPNA (adult nearside) at 25 / 75 %, CPFA (adult farside) at 50 %.
NCAP_PROTOCOLS: dict[str, tuple[tuple[str, float], ...]] = {
    "cpnco": (("cpnco", 25.0), ("cpnco", 50.0), ("cpnco", 75.0)),
    "cpna": (("cpna25", 25.0), ("cpna75", 75.0)),
    "cpfa": (("cpfa", 50.0),),
}

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


def nominal_scenes(named: dict, speeds_kmh) -> list:
    """The nominal scene of every cell of :data:`NCAP_PROTOCOLS` at the ego speeds
    ``speeds_kmh``: the named scene (``named``: name -> DrivingScene, the scenario group's)
    with its speed and its lead pedestrian's (``p0``) impact point replaced, named
    ``ncap_<protocol>_<speed>kmh_<pct>pct`` (:func:`nominal_cell` reads them back). Euro NCAP
    runs one test per cell on the nominal geometry; so does this (no draw). Raises KeyError
    naming a protocol's missing named scene."""
    out = []
    for proto, cells in NCAP_PROTOCOLS.items():
        for base_name, pct in cells:
            if base_name not in named:
                raise KeyError(f"scenario.scenes: no scene {base_name!r} (Euro NCAP {proto} "
                               f"nominal grid); found {sorted(named)}")
            base = named[base_name]
            peds = tuple(replace(p, impact_pct=pct) if p.name == "p0" else p
                         for p in base.pedestrians)
            for v in speeds_kmh:
                out.append(replace(base, name=f"ncap_{proto}_{v:.0f}kmh_{pct:.0f}pct",
                                   speed_kmh=float(v), pedestrians=peds))
    return out


def nominal_cell(scene: str) -> tuple[str, str, str] | None:
    """(protocol, speed km/h, impact %) as strings of integers from a name of
    :func:`nominal_scenes`; None for another scene."""
    parts = str(scene).split("_")
    if len(parts) != 4 or parts[0] != "ncap" or not parts[2].endswith("kmh") \
            or not parts[3].endswith("pct"):
        return None
    return parts[1], parts[2][:-3], parts[3][:-3]
