"""A scene you can watch (issue 44): a driving scene or a recording frame by frame.

Pure rendering: a :class:`Movie` of artifacts in (points, tracks, predicted paths with their
covariances, decisions, range-Doppler maps, computed by the stages' library rooms), one file out.
Each frame: a bird's-eye view (the ego car, the parked cars, the radar points with static and
moving coloured apart, the confirmed tracks with their IDs and trails, each predicted path with
the 90 % ellipse of one step (1 s ahead by default), a reference tracker's tracks beside ours
where given, the warning and AEB request from the frame they are made on) and a strip with the
range-Doppler map of the same frame (the nearest earlier frame whose map was kept).

Output: MP4 through matplotlib's FFMpegWriter where ffmpeg exists and an ``.mp4`` is asked for;
a GIF through PillowWriter otherwise (an ``.mp4`` asked for without ffmpeg is written as the
``.gif`` beside it). Written to a temporary file and moved into place atomically
(:func:`blindspot.io.write_bytes`).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from blindspot.io import write_bytes
from blindspot.typed_config import TypedConfig, setting
from blindspot.report.driving_figures import MOVING_COLOUR, STATIC_COLOUR
from blindspot.report.style import CAR_COLOUR, cell_edges, to_db

__all__ = ["CHI2_2DOF_90", "Movie", "decision_frames", "driving_movie", "ellipse_axes",
           "key_frame", "movie_writer", "recording_movie", "render_movie", "render_still",
           "WatchConfig"]

#: 90 % region of a 2-D Gaussian: Mahalanobis radius^2 = chi-square(2 dof) quantile 0.9.
CHI2_2DOF_90 = 4.605170185988092
WARNING_COLOUR = "tab:orange"
AEB_COLOUR = "tab:red"


@dataclass
class Movie:
    """What one animation shows. Data frames by column name (extra columns are ignored):

    frames: the frame numbers to draw, in order; time_s: Series frame -> time (s).
    points: frame, x_m, y_m, static. tracks: frame, track_id, x_m, y_m (confirmed rows).
    predictions: frame, track_id, step, x_m, y_m, cov_xx, cov_xy, cov_yy (or None).
    decisions: frame, warning, aeb (bool; or None). ego: frame, ego_x_m, ego_y_m, ego_yaw_deg
    (or None: a still radar at the origin). cars: parked-car polygons [[x, y], ...] (m).
    reference: another tracker's tracks (frame, track_id, x_m, y_m) drawn beside ours, or None.
    truth: frame, x_m, y_m, pedestrian (true positions, dotted) or None.
    rd: {"frame": (n,), "power": (n, R, D), "range_axis_m", "velocity_axis_mps"} or None.
    road_view: draw y (along the road) across and x (right of the ego) down, as the driving
    figures; else x across, y up (a still radar's sensor frame).
    ego_size_m: (width, length) of the ego car. ellipse_ahead_s: the predicted step whose 90 %
    ellipse is drawn (the nearest to this time ahead, s; a predictions table without
    ``t_ahead_s``: its last step).
    """

    title: str
    frames: np.ndarray
    time_s: pd.Series
    points: pd.DataFrame
    tracks: pd.DataFrame
    predictions: pd.DataFrame | None = None
    decisions: pd.DataFrame | None = None
    ego: pd.DataFrame | None = None
    cars: list = field(default_factory=list)
    reference: pd.DataFrame | None = None
    reference_label: str = "reference tracks"
    truth: pd.DataFrame | None = None
    rd: dict | None = None
    road_view: bool = False
    ego_size_m: tuple[float, float] = (1.815, 4.358)
    limits: tuple[float, float, float, float] | None = None
    ellipse_ahead_s: float = 1.0
    follow_ego_m: tuple[float, float] | None = None
    rd_max_range_m: float | None = None


def ellipse_axes(cxx: np.ndarray, cxy: np.ndarray, cyy: np.ndarray, chi2: float = CHI2_2DOF_90
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Full width, full height (m) and angle (deg, of the width's axis from +x) of the
    ``chi2`` ellipse of 2x2 covariances given by their entries (arrays of one shape)."""
    tr, det = cxx + cyy, cxx * cyy - cxy**2
    disc = np.sqrt(np.maximum(tr**2 / 4 - det, 0.0))
    l1, l2 = tr / 2 + disc, np.maximum(tr / 2 - disc, 0.0)
    angle = np.degrees(0.5 * np.arctan2(2 * cxy, cxx - cyy))
    return 2 * np.sqrt(chi2 * l1), 2 * np.sqrt(chi2 * l2), angle


def _by_frame(df: pd.DataFrame | None) -> dict:
    return {} if df is None or df.empty else dict(list(df.groupby("frame", sort=True)))


class _Painter:
    """Draws one frame of a Movie on two axes (bird's-eye view, range-Doppler strip)."""

    def __init__(self, movie: Movie, fig: Figure) -> None:
        self.m = movie
        self.fig = fig
        gs = fig.add_gridspec(1, 2 if movie.rd is not None else 1,
                              width_ratios=[3, 1] if movie.rd is not None else [1])
        self.ax = fig.add_subplot(gs[0, 0])
        self.ax_rd = fig.add_subplot(gs[0, 1]) if movie.rd is not None else None
        self.pts, self.trk = _by_frame(movie.points), _by_frame(movie.tracks)
        self.pred, self.ref = _by_frame(movie.predictions), _by_frame(movie.reference)
        self.trk_all = movie.tracks
        dec = movie.decisions
        self.first_warning = self.first_aeb = None
        if dec is not None and len(dec):
            w, a = dec[dec.warning.astype(bool)], dec[dec.aeb.astype(bool)]
            self.first_warning = int(w.frame.min()) if len(w) else None
            self.first_aeb = int(a.frame.min()) if len(a) else None
        self.limits = movie.limits or self._limits()

    def _hv(self, x, y):
        """Plot coordinates (across, up) of world x, y."""
        return (y, x) if self.m.road_view else (x, y)

    def _limits(self) -> tuple[float, float, float, float]:
        chunks = [self.m.points[["x_m", "y_m"]].dropna().to_numpy()]
        if len(self.m.tracks):
            chunks.append(self.m.tracks[["x_m", "y_m"]].to_numpy())
        if self.m.ego is not None:
            chunks.append(self.m.ego[["ego_x_m", "ego_y_m"]].to_numpy())
        xy = np.concatenate([c for c in chunks if len(c)] or [np.zeros((1, 2))])
        lo, hi = np.nanpercentile(xy, 1, axis=0) - 2, np.nanpercentile(xy, 99, axis=0) + 2
        if self.m.road_view:
            lo[0], hi[0] = max(lo[0], -12.0), min(hi[0], 12.0)
        h0, v0 = self._hv(lo[0], lo[1])
        h1, v1 = self._hv(hi[0], hi[1])
        return float(h0), float(h1), float(v0), float(v1)

    def _ego(self, f: int) -> None:
        from matplotlib.patches import Rectangle

        ax, m = self.ax, self.m
        colour = "k"
        if self.first_aeb is not None and f >= self.first_aeb:
            colour = AEB_COLOUR
        elif self.first_warning is not None and f >= self.first_warning:
            colour = WARNING_COLOUR
        w, length = m.ego_size_m
        if m.ego is None:
            h, v = self._hv(0.0, 0.0)
            ax.plot([h], [v], marker="^", color=colour, ms=9, ls="none", label="radar")
            return
        e = m.ego[m.ego.frame == f]
        if e.empty:
            return
        ex, ey = float(e.ego_x_m.iloc[0]), float(e.ego_y_m.iloc[0])
        # the ego's front bumper centre at (ex, ey), driving along +y
        x0, y0 = ex - w / 2, ey - length
        if m.road_view:
            ax.add_patch(Rectangle((y0, x0), length, w, facecolor="none", edgecolor=colour,
                                   lw=1.5, label="ego car"))
        else:
            ax.add_patch(Rectangle((x0, y0), w, length, facecolor="none", edgecolor=colour,
                                   lw=1.5, label="ego car"))

    def draw(self, f: int) -> None:
        from matplotlib.patches import Ellipse, Polygon

        ax, m = self.ax, self.m
        ax.clear()
        for i, poly in enumerate(m.cars):
            p = np.asarray(poly, float)
            h, v = self._hv(p[:, 0], p[:, 1])
            ax.add_patch(Polygon(np.c_[h, v], closed=True, facecolor=CAR_COLOUR,
                                 edgecolor="0.35", zorder=0,
                                 label="parked cars" if i == 0 else None))
        if m.truth is not None:
            for k, (_, t) in enumerate(m.truth[m.truth.frame <= f].groupby("pedestrian")):
                ax.plot(*self._hv(t.x_m, t.y_m), ":", color="tab:blue", lw=1.0)
                now = t[t.frame == f]
                ax.plot(*self._hv(now.x_m, now.y_m), "x", color="tab:blue", ms=7, mew=2,
                        label="pedestrian (truth)" if k == 0 else None)
        self._ego(f)
        p = self.pts.get(f)
        if p is not None:
            p = p.dropna(subset=["x_m"])
            st = p.static.to_numpy(bool)
            ax.scatter(*self._hv(p.x_m[st], p.y_m[st]), s=5, c=STATIC_COLOUR,
                       label=f"static points ({st.sum()})")
            ax.scatter(*self._hv(p.x_m[~st], p.y_m[~st]), s=12, c=MOVING_COLOUR,
                       label=f"moving points ({(~st).sum()})")
        r = self.ref.get(f)
        if r is not None:
            ax.scatter(*self._hv(r.x_m, r.y_m), s=70, marker="s", facecolors="none",
                       edgecolors="tab:purple", label=m.reference_label)
        t = self.trk.get(f)
        if t is not None:
            trail = self.trk_all[(self.trk_all.frame <= f)
                                 & self.trk_all.track_id.isin(t.track_id)]
            for tid, g in trail.groupby("track_id"):
                ax.plot(*self._hv(g.x_m, g.y_m), "-", color="tab:green", lw=1.2)
            ax.scatter(*self._hv(t.x_m, t.y_m), s=40, c="tab:green", marker="o",
                       edgecolors="k", zorder=5, label="our tracks")
            for _, row in t.iterrows():
                h, v = self._hv(row.x_m, row.y_m)
                ax.annotate(f"{int(row.track_id)}", (h, v), xytext=(4, 4),
                            textcoords="offset points", fontsize=8, color="darkgreen",
                            weight="bold")
        pr = self.pred.get(f)
        if pr is not None:
            for k, (tid, g) in enumerate(pr.groupby("track_id")):
                g = g.sort_values("step")
                ax.plot(*self._hv(g.x_m, g.y_m), "--", color="tab:blue", lw=1.2,
                        label="predicted path" if k == 0 else None)
                last = (g.iloc[int(np.argmin(np.abs(g.t_ahead_s.to_numpy()
                                                    - m.ellipse_ahead_s)))]
                        if "t_ahead_s" in g else g.iloc[-1])
                cxx, cyy = ((last.cov_yy, last.cov_xx) if m.road_view
                            else (last.cov_xx, last.cov_yy))
                wd, ht, ang = ellipse_axes(np.float64(cxx), np.float64(last.cov_xy),
                                           np.float64(cyy))
                ax.add_patch(Ellipse(self._hv(last.x_m, last.y_m), wd, ht, angle=ang,
                                     facecolor="tab:blue", alpha=0.15, edgecolor="tab:blue",
                                     label=f"90 % region {m.ellipse_ahead_s:g} s ahead" if k == 0
                                     else None))
        self._banner(f)
        h0, h1, v0, v1 = self.limits
        if m.follow_ego_m is not None and m.ego is not None and (m.ego.frame == f).any():
            ey = float(m.ego.ego_y_m[m.ego.frame == f].iloc[0])
            h0, h1 = ey - m.follow_ego_m[0], ey + m.follow_ego_m[1]
        ax.set_xlim(h0, h1)
        ax.set_ylim(v0, v1)
        if m.road_view:
            ax.invert_yaxis()
            ax.set_xlabel("y along the road (m)")
            ax.set_ylabel("x right of the ego (m)")
        else:
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(fontsize=6, loc="upper left", ncol=2, framealpha=0.7)
        ts = float(m.time_s.get(f, np.nan))
        ax.set_title(f"{m.title}   frame {f}, t = {ts:.2f} s", fontsize=9)
        self._rd(f)

    def _banner(self, f: int) -> None:
        ax = self.ax
        notes = []
        if self.first_warning is not None and f >= self.first_warning:
            notes.append((f"WARNING (frame {self.first_warning}, t = "
                          f"{float(self.m.time_s.get(self.first_warning, np.nan)):.2f} s)",
                          WARNING_COLOUR))
        if self.first_aeb is not None and f >= self.first_aeb:
            notes.append((f"AEB REQUEST (frame {self.first_aeb}, t = "
                          f"{float(self.m.time_s.get(self.first_aeb, np.nan)):.2f} s)",
                          AEB_COLOUR))
        for i, (text, colour) in enumerate(notes):
            ax.text(0.99, 0.97 - 0.08 * i, text, transform=ax.transAxes, ha="right", va="top",
                    fontsize=9, weight="bold", color="white",
                    bbox=dict(facecolor=colour, edgecolor="none", pad=2))

    def _rd(self, f: int) -> None:
        if self.ax_rd is None:
            return
        ax, rd = self.ax_rd, self.m.rd
        ax.clear()
        kept = np.asarray(rd["frame"])
        i = np.searchsorted(kept, f, side="right") - 1
        if i < 0:
            ax.set_title("range-Doppler: no map yet", fontsize=8)
            return
        power = np.asarray(rd["power"][i], float)
        r, v = np.asarray(rd["range_axis_m"]), np.asarray(rd["velocity_axis_mps"])
        db = to_db(power)
        ax.pcolormesh(cell_edges(v), cell_edges(r)[:power.shape[0] + 1], db[:, :len(v)],
                      cmap="viridis", vmin=float(np.percentile(db, 50)), vmax=float(db.max()),
                      shading="flat", rasterized=True)
        if self.m.rd_max_range_m is not None:
            ax.set_ylim(0.0, self.m.rd_max_range_m)
        ax.set_xlabel("radial velocity (m/s)", fontsize=8)
        ax.set_ylabel("range (m)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_title(f"range-Doppler, frame {int(kept[i])}", fontsize=8)


def movie_writer(path: Path, fps: float):
    """(writer, path actually written): FFMpegWriter for ``.mp4`` where ffmpeg exists, else
    PillowWriter and the ``.gif`` path."""
    from matplotlib.animation import FFMpegWriter, PillowWriter

    path = Path(path)
    if path.suffix.lower() == ".mp4" and FFMpegWriter.isAvailable():
        return FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"]), path
    return PillowWriter(fps=fps), path.with_suffix(".gif")


def _figure(movie: Movie, dpi: float) -> Figure:
    from matplotlib.figure import Figure as Fig

    return Fig(figsize=(10.0, 4.4) if movie.rd is not None else (7.5, 5.0), dpi=dpi,
               layout="constrained")


def render_movie(movie: Movie, path: Path, *, fps: float = 10.0, dpi: float = 72.0) -> Path:
    """Write ``movie`` as an animation at ``path`` (module docstring); returns the path written
    (``.gif`` where an ``.mp4`` could not be)."""
    if not len(movie.frames):
        raise ValueError(f"render_movie: {movie.title!r} has no frame to draw")
    writer, out = movie_writer(path, fps)
    fig = _figure(movie, dpi)
    painter = _Painter(movie, fig)
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp) / f"movie{out.suffix}"
        with writer.saving(fig, str(scratch), dpi):
            for f in movie.frames:
                painter.draw(int(f))
                writer.grab_frame()
        write_bytes(out, scratch.read_bytes())
    return out


def render_still(movie: Movie, frame: int, path: Path, *, dpi: float = 100.0) -> Path:
    """One frame of ``movie`` as a still picture (PNG) at ``path``."""
    fig = _figure(movie, dpi)
    _Painter(movie, fig).draw(int(frame))
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp) / f"still{Path(path).suffix}"
        fig.savefig(scratch, dpi=dpi)
        write_bytes(path, scratch.read_bytes())
    return Path(path)


def recording_movie(name: str, res, *, every: int = 1, max_frames: int | None = None) -> Movie:
    """The Movie of one recording: ``res`` has ``points``, ``tracks``, ``predictions``,
    ``decisions``, ``reference`` (TI's tracks) and ``first`` (a raw capture's first frame with
    ``power``, ``range_axis_m``, ``velocity_axis_mps``), each None where absent (the recordings
    stage's result); every ``every``-th frame, at most ``max_frames`` of them."""
    points = res.points
    tracks = res.tracks
    tracks = (pd.DataFrame(columns=["frame", "track_id", "x_m", "y_m"]) if tracks is None
              else tracks[tracks.confirmed.astype(bool)])
    decisions, ego, rd = res.decisions, None, None
    if decisions is not None:
        ego = decisions.assign(ego_x_m=0.0, ego_yaw_deg=0.0)[["frame", "ego_x_m", "ego_y_m",
                                                               "ego_yaw_deg"]]
    first = getattr(res, "first", None)
    if first is not None:
        rd = {"frame": np.array([0]), "power": np.asarray(first.power)[None],
              "range_axis_m": first.range_axis_m, "velocity_axis_mps": first.velocity_axis_mps}
    frames = np.sort(points.frame.unique())[::max(1, int(every))]
    if max_frames is not None:
        frames = frames[:max_frames]
    time_s = points.drop_duplicates("frame").set_index("frame").time_s
    return Movie(title=name, frames=frames, time_s=time_s, points=points, tracks=tracks,
                 predictions=res.predictions, decisions=decisions, ego=ego,
                 reference=res.reference, reference_label="TI's tracks (gtrack)", rd=rd)


def decision_frames(outcomes: pd.DataFrame | None, scene: str, *, predictor: str,
                    input_name: str = "tracker") -> tuple[int | None, int | None]:
    """(first warning frame, first AEB request frame) of ``scene`` in the safety stage's
    per-scene outcomes (columns scene, input, predictor, warn_frame, aeb_frame; -1 = none),
    None where absent or never."""
    need = {"scene", "predictor", "warn_frame", "aeb_frame"}
    if outcomes is None or need - set(outcomes.columns):
        return None, None
    row = outcomes[(outcomes.scene == scene) & (outcomes.predictor == predictor)]
    if "input" in row:
        row = row[row.input == input_name]
    if row.empty:
        return None, None
    w, a = int(row.warn_frame.iloc[0]), int(row.aeb_frame.iloc[0])
    return (w if w >= 0 else None), (a if a >= 0 else None)


def driving_movie(title: str, truth: pd.DataFrame, cars: list, points: pd.DataFrame,
                  tracks: pd.DataFrame, predictions: pd.DataFrame | None,
                  decision: tuple[int | None, int | None], rd: dict | None, *,
                  every: int = 1, ego_size_m: tuple[float, float] = (1.815, 4.358)) -> Movie:
    """The Movie of one driving scene from its artifacts: ``truth`` (the scene's rows of
    driving/truth.parquet: frame, time_s, ego_x_m, ego_y_m, ego_yaw_deg, pedestrian, x_m, y_m),
    the parked cars' polygons, its radar points (frame, x_m, y_m, static), its tracks (frame,
    track_id, x_m, y_m, confirmed and, where given, moving: only those rows are drawn), the
    predicted paths, the (warning, AEB) frames and the kept range-Doppler maps."""
    ego = truth.drop_duplicates("frame")[["frame", "time_s", "ego_x_m", "ego_y_m",
                                          "ego_yaw_deg"]]
    keep = tracks.confirmed.astype(bool)
    if "moving" in tracks:
        keep &= tracks.moving.astype(bool)
    frames = np.sort(ego.frame.unique())[::max(1, int(every))]
    warn, aeb = decision
    dec = pd.DataFrame({"frame": ego.frame})
    dec["warning"] = (dec.frame >= warn) if warn is not None else False
    dec["aeb"] = (dec.frame >= aeb) if aeb is not None else False
    ped = truth[["frame", "x_m", "y_m", "pedestrian"]]
    box = np.concatenate([np.asarray(c, float).reshape(-1, 2) for c in cars] or
                         [np.zeros((0, 2))])
    xs = np.r_[ego.ego_x_m, ped.x_m, box[:, 0] if len(box) else []]
    ys = np.r_[ego.ego_y_m, ped.y_m, box[:, 1] if len(box) else []]
    limits = (float(np.nanmin(ys)) - 6.0, float(np.nanmax(ys)) + 4.0,
              float(min(np.nanmin(xs) - 1.0, -6.0)), float(max(np.nanmax(xs) + 1.0, 6.0)))
    return Movie(title=title, frames=frames, time_s=ego.set_index("frame").time_s,
                 points=points, tracks=tracks[keep], predictions=predictions, decisions=dec,
                 ego=ego, cars=list(cars), truth=ped, rd=rd, road_view=True,
                 ego_size_m=ego_size_m, limits=limits, follow_ego_m=(8.0, 24.0),
                 rd_max_range_m=30.0)


def key_frame(movie: Movie) -> int:
    """The frame a still should show: two frames after the AEB request (else the warning, else
    three quarters through), where the predicted path and its ellipse have met the ego's."""
    frames = np.asarray(movie.frames)
    dec = movie.decisions
    for col in ("aeb", "warning"):
        if dec is not None and col in dec and dec[col].astype(bool).any():
            f = int(dec.frame[dec[col].astype(bool)].min())
            later = frames[frames >= f]
            return int(later[min(2, len(later) - 1)]) if len(later) else int(frames[-1])
    return int(frames[int(len(frames) * 0.75)])


@dataclass(frozen=True)
class WatchConfig(TypedConfig):
    """The Hydra group ``watch`` (``conf/watch/default.yaml``): which driving scene the watch
    stage animates, and how (a recording's animation: its ``animate`` key, the recordings
    stage)."""

    GROUP = "watch"

    ego_speed_kmh: float = setting(gt=0.0, le=200.0)
    predictor: str = setting()
    input: str = setting()
    rd_every: int = setting(ge=1, le=10_000)
    fps: float = setting(gt=0.0, le=120.0)
    dpi: float = setting(gt=0.0, le=600.0)
    format: str = setting(choices=("gif", "mp4"))
    scene: str = setting()
