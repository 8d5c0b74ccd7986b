"""ETH/UCY pedestrian trajectories: reading the scene files and the Social-GAN windowing.

Data layout (see ``shared/data/ethucy/README.md``): ``<root>/<fold>/{train,val,test}/*.txt``,
each file a tab-separated table ``frame  ped_id  x  y`` (metres, world frame) with frame ids
stepping by 10 (0.4 s, 2.5 fps). Folds are leave-one-scene-out: ``<fold>/test`` is one
recording in full, ``train``/``val`` hold parts of all the others.

Windowing (Social-GAN, Gupta et al. 2018, the standard benchmark protocol): a window is 20
consecutive frames (observe 8 + predict 12) of one pedestrian, who must be present in all 20;
windows start at every frame (stride 1); and a window start only counts when at least
``min_peds = 2`` pedestrians are fully present over those 20 frames (the reference loader keeps
sequences with ``num_peds > 1``). With these rules the test folds hold exactly
eth 181, hotel 1053, univ 24334, zara1 2253, zara2 5833 windows.

Frames here are *physical* frames (``(frame - first_frame) / step``); the reference loader
indexes the distinct frame ids present in the file instead. The two agree on this data set
because no pedestrian's track spans an empty frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from blindspot.traj.config import ETHUCY_FOLDS as FOLDS

__all__ = [
    "FOLDS",
    "SPLITS",
    "FRAME_STEP",
    "FRAME_PERIOD_S",
    "OBS_LEN",
    "PRED_LEN",
    "TEST_WINDOWS",
    "EthUcyDataError",
    "SceneTracks",
    "Windows",
    "default_data_dir",
    "read_scene",
    "scene_tracks",
    "sliding_windows",
    "split_files",
    "load_split",
    "random_rotations",
]

SPLITS: tuple[str, ...] = ("train", "val", "test")
FRAME_STEP = 10          # frame-id increment between annotated frames
FRAME_PERIOD_S = 0.4     # 2.5 fps
OBS_LEN = 8              # 3.2 s observed
PRED_LEN = 12            # 4.8 s predicted

#: Number of test windows per fold under the Social-GAN windowing (data README).
TEST_WINDOWS: dict[str, int] = {"eth": 181, "hotel": 1053, "univ": 24334, "zara1": 2253,
                                "zara2": 5833}


class EthUcyDataError(ValueError):
    """An ETH/UCY file or folder is missing or not in the expected format."""


def default_data_dir() -> Path:
    """``$BLINDSPOT_SHARED/data/ethucy``, defaulting to ``<repo>/../shared/data/ethucy``."""
    shared = os.environ.get("BLINDSPOT_SHARED")
    if shared:
        return Path(shared) / "data" / "ethucy"
    repo = Path(__file__).resolve().parents[3]
    return (repo / ".." / "shared" / "data" / "ethucy").resolve()


def read_scene(path: str | Path) -> np.ndarray:
    """Read one scene file.

    Args:
        path: a tab/space-separated text file with rows ``frame ped_id x y``.

    Returns:
        (R, 4) float64 array of the rows, sorted by (frame, ped_id).

    Raises:
        EthUcyDataError: missing file, wrong column count, non-numeric or non-finite values,
            or a (frame, pedestrian) pair that appears twice.
    """
    p = Path(path)
    if not p.is_file():
        raise EthUcyDataError(f"{p}: no such ETH/UCY scene file")
    try:
        rows = np.loadtxt(p, dtype=float, ndmin=2)
    except ValueError as exc:
        raise EthUcyDataError(f"{p}: expected numeric rows 'frame ped_id x y' ({exc})") from exc
    if rows.shape[0] == 0:
        raise EthUcyDataError(f"{p}: the file holds no rows")
    if rows.shape[1] != 4:
        raise EthUcyDataError(f"{p}: expected 4 columns 'frame ped_id x y', found {rows.shape[1]}")
    if not np.isfinite(rows).all():
        bad = int(np.flatnonzero(~np.isfinite(rows).all(axis=1))[0]) + 1
        raise EthUcyDataError(f"{p}: non-finite value in data row {bad}")
    order = np.lexsort((rows[:, 1], rows[:, 0]))
    rows = rows[order]
    dup = (np.diff(rows[:, 0]) == 0) & (np.diff(rows[:, 1]) == 0)
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        raise EthUcyDataError(f"{p}: frame {rows[i, 0]:g} lists pedestrian {rows[i, 1]:g} twice")
    return rows


@dataclass(frozen=True)
class SceneTracks:
    """All pedestrians of one scene on a dense frame grid.

    Attributes:
        xy: (P, F, 2) positions in metres; NaN where pedestrian p is absent in frame f.
        frames: (F,) frame ids of the grid (first frame + step * index).
        ped_ids: (P,) pedestrian ids as in the file.
        source: the file the tracks came from.
    """

    xy: np.ndarray
    frames: np.ndarray
    ped_ids: np.ndarray
    source: str


def scene_tracks(rows: np.ndarray, *, frame_step: int = FRAME_STEP,
                 source: str = "<array>") -> SceneTracks:
    """Put the rows of a scene (R, 4) on a dense (pedestrian, frame) grid.

    Raises:
        EthUcyDataError: a frame id that is not on the ``frame_step`` grid.
    """
    f0 = rows[:, 0].min()
    offset = (rows[:, 0] - f0) / frame_step
    fidx = np.rint(offset).astype(np.int64)
    off_grid = np.abs(offset - fidx) > 1e-9
    if off_grid.any():
        bad = rows[np.flatnonzero(off_grid)[0], 0]
        raise EthUcyDataError(f"{source}: frame id {bad:g} is not on the grid of step "
                              f"{frame_step} starting at {f0:g}")
    ped_ids, pidx = np.unique(rows[:, 1], return_inverse=True)
    n_frames = int(fidx.max()) + 1
    xy = np.full((ped_ids.size, n_frames, 2), np.nan)
    xy[pidx, fidx] = rows[:, 2:4]
    frames = f0 + frame_step * np.arange(n_frames)
    return SceneTracks(xy=xy, frames=frames, ped_ids=ped_ids, source=source)


def sliding_windows(tracks: SceneTracks, seq_len: int, *, min_peds: int = 2
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All fully observed windows of ``seq_len`` consecutive frames (stride 1).

    Args:
        tracks: the scene on its frame grid.
        seq_len: frames per window (20 for observe 8 + predict 12).
        min_peds: a window start counts only if at least this many pedestrians are present in
            all of its frames (2 = the Social-GAN loader's ``num_peds > 1``; 1 = no filter).

    Returns:
        ``(xy (N, seq_len, 2), ped (N,) row index into tracks.ped_ids, start (N,) first frame
        index)``, ordered by start frame then pedestrian.
    """
    if seq_len < 1:
        raise ValueError(f"seq_len: expected >= 1, found {seq_len}")
    present = np.isfinite(tracks.xy).all(axis=-1)                        # (P, F)
    P, F = present.shape
    if F < seq_len:
        return np.empty((0, seq_len, 2)), np.empty(0, np.int64), np.empty(0, np.int64)
    csum = np.concatenate([np.zeros((P, 1), np.int64), np.cumsum(present, axis=1)], axis=1)
    full = (csum[:, seq_len:] - csum[:, :-seq_len]) == seq_len           # (P, F - seq_len + 1)
    full &= (full.sum(axis=0) >= min_peds)[None, :]
    start, ped = np.nonzero(full.T)
    idx = start[:, None] + np.arange(seq_len)[None, :]
    return tracks.xy[ped[:, None], idx], ped, start


@dataclass(frozen=True)
class Windows:
    """Windows of one fold/split, concatenated over its files.

    Attributes:
        xy: (N, seq_len, 2) positions in metres (no NaN).
        track_id: (N,) a pedestrian id unique across the split's files (file-major numbering).
        start: (N,) first frame index of each window within its file.
        file_index: (N,) index into ``files``.
        files: the scene files read, sorted by name.
    """

    xy: np.ndarray
    track_id: np.ndarray
    start: np.ndarray
    file_index: np.ndarray
    files: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    def observed(self, obs_len: int = OBS_LEN) -> np.ndarray:
        """(N, obs_len, 2) the first ``obs_len`` positions."""
        return self.xy[:, :obs_len]

    def future(self, obs_len: int = OBS_LEN) -> np.ndarray:
        """(N, seq_len - obs_len, 2) the positions after the observed part."""
        return self.xy[:, obs_len:]


def split_files(data_dir: str | Path, fold: str, split: str) -> list[Path]:
    """Sorted scene files of ``<data_dir>/<fold>/<split>``.

    Raises:
        EthUcyDataError: unknown fold/split, or a folder missing or without ``.txt`` files.
    """
    if fold not in FOLDS:
        raise EthUcyDataError(f"fold: expected one of {FOLDS}, found {fold!r}")
    if split not in SPLITS:
        raise EthUcyDataError(f"split: expected one of {SPLITS}, found {split!r}")
    folder = Path(data_dir) / fold / split
    files = sorted(folder.glob("*.txt"))
    if not files:
        raise EthUcyDataError(f"{folder}: expected ETH/UCY scene files (*.txt), found none "
                              "(point --data at the folder holding eth/ hotel/ univ/ zara1/ "
                              "zara2/)")
    return files


def load_split(data_dir: str | Path, fold: str, split: str, *, seq_len: int = OBS_LEN + PRED_LEN,
               min_peds: int = 2) -> Windows:
    """Windows of one fold and split, Social-GAN style (see :func:`sliding_windows`).

    Args:
        data_dir: folder holding ``eth/ hotel/ univ/ zara1/ zara2/``.
        fold: one of :data:`FOLDS`; split: one of :data:`SPLITS`.
        seq_len: frames per window; min_peds: see :func:`sliding_windows`.
    """
    parts, ids, starts, file_idx = [], [], [], []
    offset = 0
    files = split_files(data_dir, fold, split)
    for i, path in enumerate(files):
        tracks = scene_tracks(read_scene(path), source=str(path))
        xy, ped, start = sliding_windows(tracks, seq_len, min_peds=min_peds)
        parts.append(xy)
        ids.append(ped + offset)
        starts.append(start)
        file_idx.append(np.full(ped.size, i, np.int64))
        offset += tracks.ped_ids.size
    return Windows(xy=np.concatenate(parts), track_id=np.concatenate(ids),
                   start=np.concatenate(starts), file_index=np.concatenate(file_idx),
                   files=tuple(str(f) for f in files))


def random_rotations(xy: np.ndarray, copies: int, rng: np.random.Generator) -> np.ndarray:
    """Rotated copies of windows about the origin, the standard ETH/UCY augmentation.

    Walking is the same in every direction, so a window rotated by any angle is an equally
    plausible window. Each copy of each window gets its own uniform angle in [0, 2 pi).

    Args:
        xy: (N, T, 2) windows in metres.
        copies: number of rotated copies per window (>= 0).
        rng: the random generator (seeded by the caller).

    Returns:
        (copies * N, T, 2), copy-major (all windows of copy 0, then copy 1, ...).
    """
    if int(copies) != copies or copies < 0:
        raise ValueError(f"copies: expected an integer >= 0, found {copies!r}")
    theta = rng.uniform(0.0, 2.0 * np.pi, size=(int(copies), xy.shape[0]))
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]          # (copies, N, 1)
    x, y = xy[None, ..., 0], xy[None, ..., 1]                          # (1, N, T)
    rotated = np.stack([c * x - s * y, s * x + c * y], axis=-1)        # (copies, N, T, 2)
    return rotated.reshape(-1, *xy.shape[1:])
