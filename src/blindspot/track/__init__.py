"""blindspot.track: radar points of many frames -> tracks.

Clustering of one frame's points into objects (DBSCAN), a constant-velocity Kalman filter,
Mahalanobis gating, association (GNN or JPDA), M-of-N track confirmation, deletion after misses
and coasting through occlusion: a multi-target tracker assembled from Stone Soup's parts,
configured by the Hydra group ``conf/tracker/``. It sees points (frame, time, position), never
radar cubes; traj and safety build on its tracks (``.importlinter``).

Public API: :func:`track_points` (points -> one row per live track per frame),
:class:`TrackerConfig`, :func:`cluster_points`, :class:`TrackingError`.
"""

from blindspot.track.config import TrackerConfig
from blindspot.track.tracker import TrackingError, cluster_points, track_points

__all__ = ["TrackerConfig", "TrackingError", "cluster_points", "track_points"]
