"""One processed frame's maps on disk: the writer and the reader of a ``.npz`` frame file.

The detection stage keeps one simulated frame for the paper's Fig. 6 and the recordings stage the
first frame of each real capture; both write it here, the figures read it back. The file holds
the frame's maps and axes of a :class:`blindspot.dsp.chain.FrameResult` (its detections are a
table and go to Parquet) and, optionally, the name of the scene or recording it came from:

    power, threshold : (range, doppler) float64, |X|^2 and the CFAR threshold
    mask             : (range, doppler) bool, CFAR detections
    range_axis_m     : (range,) float64, m;  velocity_axis_mps : (doppler,) float64, m/s
    spectrum         : (angles,) float64 pseudo-spectrum of the strongest moving detection,
                       empty (0,) when the frame has none
    angles_deg       : (angles,) float64, the scan grid of ``spectrum``, degrees
    spectrum_detection : int, the row of that detection in the frame's detections, -1 if none
    frame            : int, frame index;  time_s : float, s
    scene            : str, "" when not given

Written atomically (:func:`blindspot.io.atomic_open`), compressed.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from blindspot.io import atomic_open

if TYPE_CHECKING:  # pragma: no cover - typing only
    from blindspot.dsp.chain import FrameResult

__all__ = ["FRAME_KEYS", "write_frame_result", "read_frame_result"]

FRAME_KEYS = ("power", "threshold", "mask", "range_axis_m", "velocity_axis_mps", "spectrum",
              "angles_deg", "spectrum_detection", "scene", "frame", "time_s")


def write_frame_result(path: str | os.PathLike[str], result: FrameResult, *,
                       scene: str = "") -> Path:
    """Write ``result``'s maps, axes and spectrum (the keys :data:`FRAME_KEYS`) to ``path``.

    ``scene``: the scene or recording the frame belongs to (stored as a string). Returns ``path``.
    """
    with atomic_open(path, "wb") as f:
        np.savez_compressed(
            f, power=result.power, threshold=result.threshold, mask=result.mask,
            range_axis_m=result.range_axis_m, velocity_axis_mps=result.velocity_axis_mps,
            spectrum=result.spectrum if result.spectrum is not None else np.zeros(0),
            angles_deg=result.angles_deg,
            spectrum_detection=(-1 if result.spectrum_detection is None
                                else result.spectrum_detection),
            scene=scene, frame=result.frame, time_s=result.time_s)
    return Path(path)


def read_frame_result(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The arrays of a frame file by key (:data:`FRAME_KEYS`; 0-d arrays for the scalars).

    Raises ``FileNotFoundError`` for a missing file and ``ValueError`` naming the file and the
    missing keys for a file not written by :func:`write_frame_result`.
    """
    with np.load(path) as z:
        frame = {k: z[k] for k in z.files}
    missing = [k for k in FRAME_KEYS if k not in frame]
    if missing:
        raise ValueError(f"{path}: not a frame file of blindspot.dsp.frame_io (missing keys "
                         f"{missing}); rewrite it with write_frame_result")
    return frame
