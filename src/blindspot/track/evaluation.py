"""Tracks against reference tracks: the CLEAR MOT metrics (Bernardin & Stiefelhagen 2008) and ID
measures (Ristani et al. 2016) through py-motmetrics (https://github.com/cheind/py-motmetrics).

A track and a reference object may be matched in a frame when their distance is below the gate;
motmetrics matches them per frame (Hungarian assignment, keeping the previous frame's matches
where still inside the gate), counts misses, false positives and identity switches, and gives
MOTA = 1 - (misses + false positives + switches) / reference objects and MOTP = mean distance of
the matches (here in metres: the distance matrix is Euclidean, not squared).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.arrays import check_number
from blindspot.tables import check_columns

__all__ = ["MOT_METRICS", "compare_tracks", "matched_distances"]

#: motmetrics' names of what :func:`compare_tracks` returns, and ours.
MOT_METRICS = {"mota": "mota", "motp": "motp", "num_switches": "id_switches",
               "idf1": "idf1", "num_misses": "misses", "num_false_positives": "false_positives",
               "num_unique_objects": "n_reference", "mostly_tracked": "mostly_tracked",
               "num_frames": "n_frames", "num_matches": "n_matches"}


def _pairs(tracks: pd.DataFrame, reference: pd.DataFrame) -> pd.DataFrame:
    """Every (frame, reference id, track id) pair with its Euclidean distance (m)."""
    m = reference[["frame", "track_id", "x_m", "y_m"]].merge(
        tracks[["frame", "track_id", "x_m", "y_m"]], on="frame", suffixes=("_ref", "_trk"))
    return m.assign(distance_m=np.hypot(m.x_m_ref - m.x_m_trk, m.y_m_ref - m.y_m_trk))


def compare_tracks(tracks: pd.DataFrame, reference: pd.DataFrame, gate_m: float) -> dict:
    """CLEAR MOT and ID metrics of ``tracks`` against ``reference`` over the reference's frames.

    Args:
        tracks, reference: rows of ``frame`` (int), ``track_id`` (int), ``x_m``, ``y_m`` (m, one
            frame of reference); one row per object per frame. Frames of ``tracks`` absent from
            ``reference`` are not scored (the reference did not look there).
        gate_m: largest distance (m) at which a track may stand for a reference object.

    Returns:
        dict with ``mota``, ``motp`` (m), ``id_switches``, ``idf1``, ``misses``,
        ``false_positives``, ``n_reference`` (distinct reference ids), ``mostly_tracked``,
        ``n_frames``, ``n_matches``, ``median_distance_m`` (median distance of the matched
        pairs), ``matches`` (DataFrame frame, ref_id, track_id, distance_m of every match).

    Raises:
        ValueError: ``gate_m`` not a finite number > 0, or a column missing.
    """
    import motmetrics as mm

    check_number(gate_m, "gate_m", gt=0.0, unit="m", who="compare_tracks")  # inf gated all
    for name, df in (("tracks", tracks), ("reference", reference)):
        check_columns(df, {"frame", "track_id", "x_m", "y_m"}, name, who="compare_tracks")
    frames = np.unique(reference["frame"].to_numpy())
    tracks = tracks[tracks["frame"].isin(frames)]
    pairs = _pairs(tracks, reference)
    pairs = pairs[pairs.distance_m < gate_m]
    ref_by = dict(list(reference.groupby("frame")["track_id"]))
    trk_by = dict(list(tracks.groupby("frame")["track_id"]))
    pair_by = dict(list(pairs.groupby("frame")))
    acc = mm.MOTAccumulator(auto_id=False)
    for f in frames:  # motmetrics takes one frame per call
        ref = np.sort(ref_by[f].to_numpy())
        trk = np.sort(trk_by[f].to_numpy()) if f in trk_by else np.empty(0, np.int64)
        dist = np.full((len(ref), len(trk)), np.nan)
        if f in pair_by:
            p = pair_by[f]
            dist[np.searchsorted(ref, p.track_id_ref), np.searchsorted(trk, p.track_id_trk)] = (
                p.distance_m.to_numpy())
        acc.update(ref, trk, dist, frameid=int(f))
    summary = mm.metrics.create().compute(acc, metrics=list(MOT_METRICS), name="run")
    out = {ours: summary.loc["run", theirs].item() for theirs, ours in MOT_METRICS.items()}
    ev = acc.mot_events.reset_index()
    matched = ev[ev.Type.isin(["MATCH", "SWITCH"])]
    matches = pd.DataFrame({"frame": matched.FrameId.to_numpy(np.int64),
                            "ref_id": matched.OId.astype(np.int64).to_numpy(),
                            "track_id": matched.HId.astype(np.int64).to_numpy(),
                            "distance_m": matched.D.to_numpy(float)})
    out["median_distance_m"] = float(matches.distance_m.median()) if len(matches) else None
    out["matches"] = matches
    return out
