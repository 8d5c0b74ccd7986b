"""blindspot.track: radar points of many frames -> tracks.

Clustering of one frame's points into objects, filters (Kalman, IMM), gating, association,
track confirmation and deletion, coasting through occlusion: a multi-target tracker assembled
from a tracking library's parts, configured by the Hydra group ``conf/tracker/``. It sees points
(frame, time, position, Doppler), never radar cubes; traj and safety build on its tracks
(``.importlinter``).
"""
