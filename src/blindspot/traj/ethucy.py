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

What the loaders leave out, and how they say so (issue 9, item 5):

* *Defective rows* (a non-finite value, a (frame, pedestrian) pair listed twice, a frame id off
  the ``frame_step`` grid) are refused with :class:`EthUcyDataError` by default
  (``bad_rows="raise"``, the benchmark must not change silently); with ``bad_rows="skip"`` they
  are dropped and one :class:`EthUcySkipWarning` per file gives the counts.
* *Protocol exclusions* (a pedestrian whose track has a gap, one too short for a window, a
  window start without ``min_peds`` pedestrians) are how the standard benchmark is defined and
  occur in every real file, so they are not warned about: they are counted in a
  :class:`SkipReport` per file (``Windows.skipped``, ``sliding_windows(..., report=True)``).
* A scene annotated on another frame step than the declared one (e.g. every 20 frame ids, a copy
  at 1.25 fps; Trajectron++ issue 67) is refused, never windowed: the step is inferred as the
  most common difference between a pedestrian's consecutive frame ids (gaps give multiples of
  it and do not move the mode) and :class:`EthUcyDataError` names the file, both steps and how
  many pedestrians and frame pairs support the inferred one. Refusing rather than warning: at
  another step a 20-frame window is another duration, so no number computed from it is the
  benchmark's. Pass ``frame_step`` to read such a file on purpose.
* A split that yields no window at all is an :class:`EthUcyDataError` saying why (the files,
  their track counts, the longest track against the window length needed).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from blindspot.arrays import check_array, check_count, check_number
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
    "EthUcySkipWarning",
    "SkipReport",
    "BAD_ROWS",
    "infer_frame_step",
    "SceneTracks",
    "Windows",
    "default_data_dir",
    "read_scene",
    "scene_tracks",
    "sliding_windows",
    "split_files",
    "load_split",
    "resample_tracks",
    "random_rotations",
    "neighbour_tracks",
]

SPLITS: tuple[str, ...] = ("train", "val", "test")
FRAME_STEP = 10          # frame-id increment between annotated frames
FRAME_PERIOD_S = 0.4     # 2.5 fps
OBS_LEN = 8              # 3.2 s observed
PRED_LEN = 12            # 4.8 s predicted

#: Number of test windows per fold under the Social-GAN windowing (data README).
TEST_WINDOWS: dict[str, int] = {"eth": 181, "hotel": 1053, "univ": 24334, "zara1": 2253,
                                "zara2": 5833}


BAD_ROWS: tuple[str, ...] = ("raise", "skip")   # what a loader does with a defective row
#: The largest frame or pedestrian id read as one: 1e8 video frames are 46 days at 25 fps (the
#: real scenes' ids stay below 2e4). A larger id is a corrupted row, refused before any grid.
MAX_ID = 10**8
#: The largest (pedestrian x frame) grid a scene is put on (2e7 cells, 320 MB of positions; the
#: largest real scene needs 7e5): the frame span comes from the file, so a stray frame id far
#: from the others is refused naming its row instead of allocating the span.
MAX_GRID_CELLS = 2 * 10**7
#: what a resampling step counts (resample_tracks, load_split's time_steps), for their errors
_STEP_UNIT = "annotated frames between resampled frames"


class EthUcyDataError(ValueError):
    """An ETH/UCY file or folder is missing or not in the expected format."""


class EthUcySkipWarning(UserWarning):
    """Defective rows of an ETH/UCY file were dropped (``bad_rows="skip"``); one per file."""


@dataclass(frozen=True)
class SkipReport:
    """What one scene file lost on its way to windows, and why (counts).

    Attributes:
        source: the file.
        rows: data rows read.
        nan_rows: rows with a non-finite value (dropped with ``bad_rows="skip"``).
        bad_id_rows: rows whose frame or pedestrian id is not a whole number in [0,
            :data:`MAX_ID`] (dropped with ``bad_rows="skip"``).
        duplicate_rows: repeated (frame, pedestrian) rows dropped (the first in file order kept).
        off_grid_rows: rows whose frame id is off the ``frame_step`` grid (dropped).
        pedestrians: pedestrians left after the row checks.
        peds_with_gaps: pedestrians absent in a frame between their first and last (windows
            across the gap are not formed).
        peds_too_short: pedestrians with no run of ``seq_len`` consecutive frames (no window).
        peds_without_neighbour: pedestrians with such a run but no start where ``min_peds``
            pedestrians are fully present (no window).
        longest_track: longest run of consecutive present frames of any pedestrian, frames.
        seq_len: frames per window (None before windowing).
        windows: windows formed.
    """

    source: str
    rows: int = 0
    nan_rows: int = 0
    bad_id_rows: int = 0
    duplicate_rows: int = 0
    off_grid_rows: int = 0
    pedestrians: int = 0
    peds_with_gaps: int = 0
    peds_too_short: int = 0
    peds_without_neighbour: int = 0
    longest_track: int = 0
    seq_len: int | None = None
    windows: int = 0

    def defects(self) -> str:
        """The dropped defective rows in words ('' when none)."""
        parts = [f"{n} {what}" for n, what in (
            (self.nan_rows, "rows with a non-finite value"),
            (self.bad_id_rows, f"rows with a frame or pedestrian id not a whole number in [0, "
                               f"{MAX_ID:g}]"),
            (self.duplicate_rows, "repeated (frame, pedestrian) rows"),
            (self.off_grid_rows, "rows with a frame id off the grid")) if n]
        return ", ".join(parts)

    def summary(self) -> str:
        """One line: the file, its tracks, the longest one and what was left out."""
        text = (f"{self.source}: {self.pedestrians} tracks, longest {self.longest_track} "
                f"consecutive frames")
        if self.seq_len is not None:
            text += (f" (a window needs {self.seq_len}); {self.windows} windows; "
                     f"{self.peds_too_short} tracks too short, {self.peds_with_gaps} with gaps, "
                     f"{self.peds_without_neighbour} without a neighbour over a full window")
        if self.defects():
            text += f"; dropped {self.defects()}"
        return text


def default_data_dir() -> Path:
    """``$BLINDSPOT_SHARED/data/ethucy``, defaulting to ``<repo>/../shared/data/ethucy``."""
    shared = os.environ.get("BLINDSPOT_SHARED")
    if shared:
        return Path(shared) / "data" / "ethucy"
    repo = Path(__file__).resolve().parents[3]
    return (repo / ".." / "shared" / "data" / "ethucy").resolve()


def read_scene(path: str | Path, *, bad_rows: str = "raise") -> np.ndarray:
    """Read one scene file (ETH: Pellegrini et al. 2009; UCY: Lerner et al. 2007).

    Args:
        path: a tab/space-separated text file with rows ``frame ped_id x y`` (x, y in metres).
        bad_rows: "raise" (default) refuses a row with a non-finite value or a (frame,
            pedestrian) pair listed twice; "skip" drops them (a repeated pair keeps its first
            row in file order) with one :class:`EthUcySkipWarning` giving the counts.

    Returns:
        (R, 4) float64 array of the rows (frame, ped_id, x_m, y_m), sorted by (frame, ped_id).

    Raises:
        EthUcyDataError: missing file, wrong column count, non-numeric values, no row, or (with
            ``bad_rows="raise"``) a non-finite value, a frame or pedestrian id that is not a
            whole number in [0, :data:`MAX_ID`] (a corrupted id: named with its data row), or a
            repeated (frame, pedestrian) pair.
    """
    rows, report = _read_rows(path, bad_rows)
    _warn_defects(report)
    return rows


def _read_rows(path: str | Path, bad_rows: str) -> tuple[np.ndarray, SkipReport]:
    """:func:`read_scene` without the warning: the rows and their :class:`SkipReport`."""
    if bad_rows not in BAD_ROWS:
        raise EthUcyDataError(f"bad_rows: expected one of {BAD_ROWS}, found {bad_rows!r}")
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
    n_rows = rows.shape[0]
    finite = np.isfinite(rows).all(axis=1)
    if not finite.all() and bad_rows == "raise":
        bad = np.flatnonzero(~finite)
        raise EthUcyDataError(f"{p}: {bad.size} of {n_rows} data rows hold a non-finite value "
                              f"(first: data row {bad[0] + 1}); pass bad_rows='skip' to drop them")
    ids = rows[:, :2]
    with np.errstate(invalid="ignore"):
        bad_id = finite & ~((ids >= 0) & (ids <= MAX_ID) & (ids == np.round(ids))).all(axis=1)
    if bad_id.any() and bad_rows == "raise":
        i = int(np.flatnonzero(bad_id)[0])
        raise EthUcyDataError(f"{p}: data row {i + 1}: frame {rows[i, 0]:g}, pedestrian "
                              f"{rows[i, 1]:g}: expected ids that are whole numbers in [0, "
                              f"{MAX_ID:g}] (a corrupted id?); {int(bad_id.sum())} such row(s) "
                              "in all; pass bad_rows='skip' to drop them")
    rows = rows[finite & ~bad_id]
    order = np.lexsort((np.arange(rows.shape[0]), rows[:, 1], rows[:, 0]))   # stable: file order
    rows = rows[order]
    dup = np.concatenate([[False], (np.diff(rows[:, 0]) == 0) & (np.diff(rows[:, 1]) == 0)])
    if dup.any() and bad_rows == "raise":
        i = int(np.flatnonzero(dup)[0])
        raise EthUcyDataError(f"{p}: frame {rows[i, 0]:g} lists pedestrian {rows[i, 1]:g} twice "
                              f"({int(dup.sum())} repeated (frame, pedestrian) rows in all); "
                              "pass bad_rows='skip' to keep the first of each")
    if not rows[~dup].size:
        raise EthUcyDataError(f"{p}: no valid row left of {n_rows} "
                              f"({int((~finite).sum())} with a non-finite value, "
                              f"{int(bad_id.sum())} with a bad id)")
    report = SkipReport(source=str(p), rows=n_rows, nan_rows=int((~finite).sum()),
                        bad_id_rows=int(bad_id.sum()), duplicate_rows=int(dup.sum()))
    return rows[~dup], report


def _warn_defects(report: SkipReport) -> None:
    if report.defects():
        warnings.warn(f"{report.source}: dropped {report.defects()} of {report.rows} rows",
                      EthUcySkipWarning, stacklevel=3)


def infer_frame_step(rows: np.ndarray) -> tuple[int | None, int, int, int]:
    """The frame-id step of a scene: the most common difference between a pedestrian's
    consecutive frame ids (a gap gives a multiple of the step and does not move the mode).

    Args:
        rows: (R, 4) rows ``frame ped_id x y`` (any order).

    Returns:
        ``(step, n_peds, n_pairs, n_all_pairs)``: the inferred step (None when no pedestrian is
        seen twice), how many pedestrians and consecutive-frame pairs step by it, and the number
        of consecutive pairs in all.

    Raises:
        EthUcyDataError: ``rows`` not a finite real (R, 4) array.
    """
    rows = check_array(rows, "rows", ("R", 4), error=EthUcyDataError, who="infer_frame_step")
    r = rows[np.lexsort((rows[:, 0], rows[:, 1]))]
    same = np.diff(r[:, 1]) == 0
    diff = np.diff(r[:, 0])[same]
    diff = diff[diff > 0]
    if diff.size == 0:
        return None, 0, 0, 0
    steps, counts = np.unique(diff, return_counts=True)
    step = steps[np.argmax(counts)]
    peds = np.unique(r[1:, 1][same][np.diff(r[:, 0])[same] == step])
    step_out = int(step) if float(step).is_integer() else float(step)
    return step_out, int(peds.size), int(counts.max()), int(diff.size)


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
                 source: str = "<array>", bad_rows: str = "raise") -> SceneTracks:
    """Put the rows of a scene (R, 4) ``frame ped_id x y`` on a dense (pedestrian, frame) grid.

    Args:
        rows: (R, 4) rows as :func:`read_scene` returns them.
        frame_step: the declared frame-id step between annotated frames (ETH/UCY: 10 = 0.4 s).
        source: the file name used in errors and warnings.
        bad_rows: "raise" refuses a frame id off the grid; "skip" drops those rows with one
            :class:`EthUcySkipWarning` giving the count.

    Raises:
        EthUcyDataError: rows not shaped (R, 4) or not finite; a frame step inferred from the
            data (:func:`infer_frame_step`) that is not ``frame_step``; a frame id off the grid;
            frame ids spanning a grid beyond :data:`MAX_GRID_CELLS` (names the farthest row).
    """
    tracks, report = _scene_tracks(rows, frame_step, source, bad_rows)
    _warn_defects(report)
    return tracks


def _scene_tracks(rows: np.ndarray, frame_step: int, source: str, bad_rows: str,
                  report: SkipReport | None = None) -> tuple[SceneTracks, SkipReport]:
    """:func:`scene_tracks` without the warning: the grid and the :class:`SkipReport`."""
    rows = check_array(rows, "rows", ("R", 4), error=EthUcyDataError, who=source)
    if bad_rows not in BAD_ROWS:
        raise EthUcyDataError(f"bad_rows: expected one of {BAD_ROWS}, found {bad_rows!r}")
    frame_step = check_count(frame_step, "frame_step", ge=1, error=EthUcyDataError, who=source)
    report = report if report is not None else SkipReport(source=source, rows=rows.shape[0])
    if rows.shape[0] == 0:
        raise EthUcyDataError(f"{source}: no rows")
    bad_id = ~((rows[:, :2] >= 0) & (rows[:, :2] <= MAX_ID)).all(axis=1)
    if bad_id.any():
        i = int(np.flatnonzero(bad_id)[0])
        raise EthUcyDataError(f"{source}: row {i}: frame {rows[i, 0]:g}, pedestrian "
                              f"{rows[i, 1]:g}: expected ids in [0, {MAX_ID:g}] (a corrupted "
                              f"id?); {int(bad_id.sum())} such row(s) in all")
    step, n_peds, n_pairs, n_all = infer_frame_step(rows)
    # the grid's phase is the most common frame id modulo the step, so one stray first row
    # cannot push every other row off the grid
    residue = np.mod(rows[:, 0], frame_step)
    phases, counts = np.unique(residue, return_counts=True)
    f0 = rows[residue == phases[np.argmax(counts)], 0].min()
    offset = (rows[:, 0] - f0) / frame_step
    fidx = np.rint(offset).astype(np.int64)
    off_grid = (np.abs(offset - fidx) > 1e-9) | (fidx < 0)
    first_off = (f" (frame id {rows[np.flatnonzero(off_grid)[0], 0]:g} is not on the grid of "
                 f"step {frame_step} starting at {f0:g}; {int(off_grid.sum())} of "
                 f"{rows.shape[0]} rows off the grid)") if off_grid.any() else ""
    if step is not None and step != frame_step:
        total = np.unique(rows[:, 1]).size
        raise EthUcyDataError(
            f"{source}: frame ids step by {step:g}, not the declared {frame_step}: "
            f"{n_pairs} of {n_all} consecutive-frame pairs of {n_peds} of {total} pedestrians "
            f"step by {step:g} ({n_all - n_pairs} by other amounts){first_off}. At another "
            f"step a window of 20 frames is not the protocol's 8 s (0.4 s per frame); resample "
            "the file, or pass frame_step to read it on purpose")
    if off_grid.any():
        if bad_rows == "raise":
            raise EthUcyDataError(f"{source}: {first_off[2:-1]}; pass bad_rows='skip' to drop "
                                  "them")
        rows, fidx = rows[~off_grid], fidx[~off_grid]
    ped_ids, pidx = np.unique(rows[:, 1], return_inverse=True)
    n_frames = int(fidx.max()) + 1
    if ped_ids.size * n_frames > MAX_GRID_CELLS:
        # the row farthest from the scene's median frame: a corrupted id, far off the others
        far = int(np.argmax(np.abs(fidx - np.median(fidx))))
        raise EthUcyDataError(
            f"{source}: frame ids span {n_frames} frames of step {frame_step} for "
            f"{ped_ids.size} pedestrians, a grid of {ped_ids.size * n_frames:.3g} cells beyond "
            f"{MAX_GRID_CELLS:.3g}; the farthest row from the others is row {far} (frame "
            f"{rows[far, 0]:g}, pedestrian {rows[far, 1]:g}): a corrupted frame id?")
    xy = np.full((ped_ids.size, n_frames, 2), np.nan)
    xy[pidx, fidx] = rows[:, 2:4]
    frames = f0 + frame_step * np.arange(n_frames)
    report = replace(report, off_grid_rows=int(off_grid.sum()), pedestrians=int(ped_ids.size))
    return SceneTracks(xy=xy, frames=frames, ped_ids=ped_ids, source=source), report


def sliding_windows(tracks: SceneTracks, seq_len: int, *, min_peds: int = 2,
                    report: bool = False):
    """All fully observed windows of ``seq_len`` consecutive frames (stride 1).

    Args:
        tracks: the scene on its frame grid.
        seq_len: frames per window (20 for observe 8 + predict 12).
        min_peds: a window start counts only if at least this many pedestrians are present in
            all of its frames (2 = the Social-GAN loader's ``num_peds > 1``; 1 = no filter).
        report: also return a :class:`SkipReport` counting the pedestrians left out (gaps, too
            short, no neighbour) and the longest track.

    Returns:
        ``(xy (N, seq_len, 2), ped (N,) row index into tracks.ped_ids, start (N,) first frame
        index)``, ordered by start frame then pedestrian; with ``report`` a fourth item, the
        :class:`SkipReport`.

    Raises:
        EthUcyDataError: ``seq_len`` or ``min_peds`` not an integer >= 1.
    """
    seq_len = check_count(seq_len, "seq_len", ge=1, error=EthUcyDataError, who=tracks.source)
    min_peds = check_count(min_peds, "min_peds", ge=1, error=EthUcyDataError, who=tracks.source)
    present = np.isfinite(tracks.xy).all(axis=-1)                        # (P, F)
    P, F = present.shape
    csum = np.concatenate([np.zeros((P, 1), np.int64), np.cumsum(present, axis=1)], axis=1)
    if F >= seq_len:
        full = (csum[:, seq_len:] - csum[:, :-seq_len]) == seq_len       # (P, F - seq_len + 1)
    else:
        full = np.zeros((P, 0), bool)
    has_run = full.any(axis=1)
    full &= (full.sum(axis=0) >= min_peds)[None, :]
    start, ped = np.nonzero(full.T)
    idx = start[:, None] + np.arange(seq_len)[None, :]
    xy = tracks.xy[ped[:, None], idx].reshape(-1, seq_len, 2)
    if not report:
        return xy, ped, start
    # gaps: absent frames between a pedestrian's first and last present frame
    seen = present.any(axis=1)
    first = np.argmax(present, axis=1)
    last = F - 1 - np.argmax(present[:, ::-1], axis=1)
    gaps = seen & (csum[:, -1] < last - first + 1)
    # longest run of consecutive present frames (vectorised: distance to the last reset)
    frame = np.arange(F)[None, :]
    reset = np.maximum.accumulate(np.where(present, -1, frame), axis=1)
    run = np.where(present, frame - reset, 0)
    skips = SkipReport(
        source=tracks.source, pedestrians=int(P), peds_with_gaps=int(gaps.sum()),
        peds_too_short=int((~has_run).sum()),
        peds_without_neighbour=int((has_run & ~full.any(axis=1)).sum()),
        longest_track=int(run.max()) if run.size else 0, seq_len=int(seq_len),
        windows=int(ped.size))
    return xy, ped, start, skips


def resample_tracks(tracks: SceneTracks, step: float) -> SceneTracks:
    """The scene sampled every ``step`` grid frames: each pedestrian's position at frame index
    ``k * step`` (k = 0, 1, ...), linearly interpolated between the two annotated frames around
    it, absent where either is; a time on an annotated frame takes that frame alone (present
    where it is, whatever the next frame holds).

    A window of the resampled scene spans ``step`` times the time of one on the original grid
    while it is read as 0.4 s per frame: the walk as a recording whose annotations are
    ``step`` x 0.4 s apart but labelled 0.4 s, as the Social-GAN file of the eth scene is (its
    frame ids step by 10 where the original annotation of the same positions steps by 6, so
    each labelled 0.4 s spans 10 / 6 x 0.4 s of walking; agrimgupta92/sgan issue 84,
    StanfordASL/Trajectron-plus-plus issue 67). ``step`` = 1 returns the scene unchanged.

    Raises:
        EthUcyDataError: ``step`` not a finite real number >= 1 (a string or a bool included).
    """
    step = check_number(step, "step", ge=1.0, unit=_STEP_UNIT, error=EthUcyDataError,
                        who=tracks.source)
    if step == 1.0:
        return tracks
    n_frames = tracks.xy.shape[1]
    t = np.arange(int(np.floor((n_frames - 1) / step + 1e-9)) + 1) * step
    lo = np.floor(t + 1e-9).astype(np.int64)
    w = np.clip(t - lo, 0.0, None)[None, :, None]
    hi = np.minimum(lo + 1, n_frames - 1)
    a, b = tracks.xy[:, lo], tracks.xy[:, hi]
    xy = np.where(w < 1e-9, a, (1.0 - w) * a + w * b)     # on a grid frame: that frame alone
    id_step = tracks.frames[1] - tracks.frames[0] if n_frames > 1 else 0
    return replace(tracks, xy=xy, frames=tracks.frames[0] + id_step * t)


@dataclass(frozen=True)
class Windows:
    """Windows of one fold/split, concatenated over its files.

    Attributes:
        xy: (N, seq_len, 2) positions in metres (no NaN).
        track_id: (N,) a pedestrian id unique across the split's files (file-major numbering).
        start: (N,) first frame index of each window within its file (of its resampled grid
            for windows of a step other than 1, :func:`load_split`'s ``time_steps``).
        file_index: (N,) index into ``files``.
        files: the scene files read, sorted by name.
        skipped: one :class:`SkipReport` per file, in ``files`` order.
        neighbours: (N, K, obs_len, 2) the observed positions (metres, world frame) of the K
            pedestrians nearest to each window's pedestrian at its last observed frame (NaN
            where a neighbour is absent in a frame, or where fewer than K are in the scene);
            None unless :func:`load_split` was asked for ``neighbours``.
    """

    xy: np.ndarray
    track_id: np.ndarray
    start: np.ndarray
    file_index: np.ndarray
    files: tuple[str, ...]
    skipped: tuple[SkipReport, ...] = field(default=())
    neighbours: np.ndarray | None = None

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
               min_peds: int = 2, frame_step: int = FRAME_STEP, bad_rows: str = "raise",
               neighbours: int = 0, obs_len: int = OBS_LEN,
               time_steps: tuple[float, ...] = (1.0,)) -> Windows:
    """Windows of one fold and split, Social-GAN style (see :func:`sliding_windows`).

    Args:
        data_dir: folder holding ``eth/ hotel/ univ/ zara1/ zara2/``.
        fold: one of :data:`FOLDS`; split: one of :data:`SPLITS`.
        seq_len: frames per window; min_peds: see :func:`sliding_windows`.
        frame_step: declared frame-id step (:func:`scene_tracks`); bad_rows: "raise" or "skip"
            defective rows (:func:`read_scene`, :func:`scene_tracks`).
        neighbours: K > 0 also gathers each window's K nearest other pedestrians over its
            first ``obs_len`` frames (:func:`neighbour_tracks`, ``Windows.neighbours``).
        time_steps: each file's windows at every one of these distinct steps of its grid
            (:func:`resample_tracks`; 1 = as annotated, and must be among them), pooled: a
            training augmentation of recordings at another annotation rate. A resampled window
            keeps its pedestrian's ``track_id``; its ``start`` counts frames of the resampled
            grid (nothing marks which step a window came from); the file's
            :class:`SkipReport` counts the annotated grid's windows alone. Each step's grid
            starts at the file's first frame (one phase of the resampled grid).

    Returns:
        :class:`Windows` with ``xy`` (N, seq_len, 2) metres and one :class:`SkipReport` per file
        in ``skipped``. Defective rows dropped with ``bad_rows="skip"`` give one
        :class:`EthUcySkipWarning` per file.

    Raises:
        EthUcyDataError: see :func:`split_files`, :func:`read_scene`, :func:`scene_tracks`; and
            when no file of the split yields a window (the message lists each file's tracks
            and its longest track against ``seq_len``); ``time_steps`` not a tuple or list of
            distinct finite numbers >= 1 holding 1 (names the element).
    """
    neighbours = check_count(neighbours, "neighbours", error=EthUcyDataError, who="load_split")
    if not isinstance(time_steps, (tuple, list)):
        raise EthUcyDataError(f"load_split: time_steps: expected a tuple or list of steps "
                              f"holding 1 (the annotated grid), found {time_steps!r}")
    steps = tuple(check_number(v, f"time_steps[{i}]", ge=1.0, unit=_STEP_UNIT,
                               error=EthUcyDataError, who="load_split")
                  for i, v in enumerate(time_steps))
    if 1.0 not in steps or len(set(steps)) != len(steps):
        raise EthUcyDataError(f"load_split: time_steps: expected distinct steps holding 1 (the "
                              f"annotated grid), found {list(time_steps)!r}")
    parts, ids, starts, file_idx, reports, nbs = [], [], [], [], [], []
    offset = 0
    files = split_files(data_dir, fold, split)
    for i, path in enumerate(files):
        rows, read = _read_rows(path, bad_rows)
        annotated, grid = _scene_tracks(rows, frame_step, str(path), bad_rows, read)
        _warn_defects(grid)
        for step in steps:
            tracks = resample_tracks(annotated, step)
            xy, ped, start, skips = sliding_windows(tracks, seq_len, min_peds=min_peds,
                                                    report=True)
            if step == 1.0:
                reports.append(replace(skips, rows=grid.rows, nan_rows=grid.nan_rows,
                                       duplicate_rows=grid.duplicate_rows,
                                       off_grid_rows=grid.off_grid_rows))
            parts.append(xy)
            if neighbours:
                nbs.append(neighbour_tracks(tracks, ped, start, neighbours, obs_len))
            ids.append(ped + offset)
            starts.append(start)
            file_idx.append(np.full(ped.size, i, np.int64))
        offset += annotated.ped_ids.size
    windows = Windows(xy=np.concatenate(parts), track_id=np.concatenate(ids),
                      start=np.concatenate(starts), file_index=np.concatenate(file_idx),
                      files=tuple(str(f) for f in files), skipped=tuple(reports),
                      neighbours=np.concatenate(nbs) if neighbours else None)
    if len(windows) == 0:
        raise EthUcyDataError(
            f"{Path(data_dir) / fold / split}: no window of {seq_len} consecutive frames with "
            f"at least {min_peds} pedestrians present in {len(files)} files: "
            + "; ".join(r.summary() for r in reports))
    return windows


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

    Raises:
        EthUcyDataError: ``xy`` not a finite real (N, T, 2) array, ``copies`` not an integer >= 0.
    """
    xy = check_array(xy, "xy", ("N", "T", 2), error=EthUcyDataError, who="random_rotations")
    copies = check_count(copies, "copies", error=EthUcyDataError, who="random_rotations")
    theta = rng.uniform(0.0, 2.0 * np.pi, size=(int(copies), xy.shape[0]))
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]          # (copies, N, 1)
    x, y = xy[None, ..., 0], xy[None, ..., 1]                          # (1, N, T)
    rotated = np.stack([c * x - s * y, s * x + c * y], axis=-1)        # (copies, N, T, 2)
    return rotated.reshape(-1, *xy.shape[1:])


def neighbour_tracks(tracks: SceneTracks, ped: np.ndarray, start: np.ndarray, k: int,
                     obs_len: int = OBS_LEN, *, chunk: int = 4096) -> np.ndarray:
    """The observed tracks of the ``k`` pedestrians nearest to each window's pedestrian.

    The social context of the ETH/UCY literature (Alahi et al. 2016, "Social LSTM"; Gupta et
    al. 2018, "Social GAN") is every other pedestrian of the same frames; here the ``k`` nearest
    (Euclidean distance at the window's last observed frame ``start + obs_len - 1``, among the
    pedestrians present in that frame), nearest first, each with its positions over the
    window's ``obs_len`` observed frames. Only observed frames are read: nothing of the future.

    Args:
        tracks: the scene (:func:`scene_tracks`), xy (P, F, 2) metres, NaN where absent.
        ped: (N,) row of each window's pedestrian in ``tracks.xy``.
        start: (N,) first frame index of each window.
        k: neighbours kept (>= 1).
        obs_len: observed frames per window.
        chunk: windows handled at once (bounds the (chunk, P) distance matrix's memory).

    Returns:
        (N, k, obs_len, 2) positions in metres; NaN where the neighbour is absent in a frame and
        for every frame of a slot left empty (fewer than ``k`` others present).

    Raises:
        EthUcyDataError: ``k`` or ``obs_len`` not an integer >= 1, a window reaching past the
            scene's last frame.
    """
    k = check_count(k, "k", ge=1, error=EthUcyDataError, who=tracks.source)
    obs_len = check_count(obs_len, "obs_len", ge=1, error=EthUcyDataError, who=tracks.source)
    ped, start = np.asarray(ped, np.int64), np.asarray(start, np.int64)
    P, F = tracks.xy.shape[:2]
    if ped.size and (start.max() + obs_len > F or ped.max() >= P):
        raise EthUcyDataError(f"{tracks.source}: a window reaches past the scene's {F} frames "
                              f"or {P} pedestrians")
    out = np.full((ped.size, k, obs_len, 2), np.nan)
    kk = min(k, max(P - 1, 0))
    if kk == 0:
        return out
    frames = np.arange(obs_len)
    for lo in range(0, ped.size, chunk):                 # memory bound, not one loop per window
        p, s = ped[lo:lo + chunk], start[lo:lo + chunk]
        last = s + obs_len - 1
        here = tracks.xy[:, last].transpose(1, 0, 2)                          # (n, P, 2)
        d = np.linalg.norm(here - tracks.xy[p, last][:, None, :], axis=-1)    # (n, P)
        d = np.where(np.isfinite(d), d, np.inf)
        d[np.arange(p.size), p] = np.inf                                      # not oneself
        near = np.argpartition(d, kk - 1, axis=1)[:, :kk] if kk < P else np.argsort(d, 1)
        near = np.take_along_axis(near, np.argsort(np.take_along_axis(d, near, 1), 1), 1)[:, :kk]
        dist = np.take_along_axis(d, near, 1)                                 # (n, kk)
        nb = tracks.xy[near[:, :, None], (s[:, None] + frames[None, :])[:, None, :]]
        nb[~np.isfinite(dist)] = np.nan                                       # empty slots
        out[lo:lo + chunk, :kk] = nb
    return out
