"""Multi-target tracking of radar points: DBSCAN objects per frame -> Stone Soup tracks.

The tracker is assembled from Stone Soup's typed parts (https://stonesoup.readthedocs.io, v1.9)
the way its tutorials read:

* objects: the points of one frame clustered with scikit-learn's DBSCAN (extended targets: a
  person gives many points on real data); one measurement per object, its centroid;
* filter: a constant-velocity Kalman filter per track, state ``[x, vx, y, vy]``
  (``CombinedLinearGaussianTransitionModel`` of two ``ConstantVelocity`` models,
  ``KalmanPredictor`` / ``KalmanUpdater``, measurement model ``LinearGaussian`` on x and y);
* gating: ``DistanceHypothesiser`` with the ``Mahalanobis`` measure (GNN) or
  ``PDAHypothesiser`` (JPDA), gate = chi-square quantile of ``gate_probability``, 2 dof;
* association: ``GNNWith2DAssignment`` (global nearest neighbour) or ``JPDA`` (the posterior
  a Gaussian-mixture reduction of the weighted hypotheses, ``gm_reduce_single``). GNN runs
  the same arithmetic on arrays (:func:`_gnn_stage`: every track's prediction, gate and
  update stacked, scipy's assignment on Stone Soup's cost matrix), byte-equal to the Stone Soup
  objects' path, which stays as its reference (``_Parts.fast``) and for JPDA: a Python object
  per track, hypothesis and detection cost ~0.3 ms per track and frame, the driving scenes'
  hundreds of static objects made it the whole tracker's time;
* initiation: ``SimpleMeasurementInitiator`` from every object no live track took, velocity
  prior zero with ``init_velocity_std_mps``;
* management: M-of-N confirmation of tentative tracks, deletion of confirmed tracks silent
  longer than ``max_misses`` frames take (frames of ``count_period_s``: a group at another frame
  rate gets the same times, :meth:`TrackerConfig.counts_at`): the rule of Stone Soup's
  ``UpdateTimeDeleter`` with ``time_since_update`` = (``max_misses`` + 1/2) frame periods (the
  group's median frame interval), so "missed frames" means the time they span whether the
  silence comes as frames without points or as no frames at all (on regular frames: the
  deletions of ``UpdateTimeStepsDeleter(max_misses + 1)``, tested); until then a track coasts
  (prediction only), so a person who reappears keeps their track. A tentative track is
  likewise deleted once its ``confirm_n`` frames' time has passed. Behind a sensor's Doppler
  notch (``min_detectable_speed_mps``) a silent track coasts through it and, seen stopping, is
  held (:mod:`blindspot.track.stopped`).

The Kalman recursion is sequential in time, so frames are stepped one after another per group;
clustering runs once over every frame of every group (one DBSCAN call).
"""

from __future__ import annotations

import copy
import datetime as dt
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import pandas as pd
from scipy.stats import chi2
from sklearn.cluster import DBSCAN

from blindspot.arrays import check_count, check_number
from blindspot.tables import check_columns
from blindspot.parallel import parallel_map
from blindspot.track.config import TrackerConfig
from blindspot.track.moving import doppler_motion_log_ratio
from blindspot.track.stopped import held_state, notch_update, seen_slowing, still

__all__ = ["INPUT_COLUMNS", "OUTPUT_COLUMNS", "TrackingError", "cluster_points", "label_objects",
           "track_points"]

#: Required input columns (``group``, ``velocity_mps``, ``velocity_over_ground_mps`` optional).
INPUT_COLUMNS = ("frame", "time_s", "x_m", "y_m")
#: Output columns after the optional ``group``.
OUTPUT_COLUMNS = ("frame", "time_s", "track_id", "x_m", "y_m", "vx_mps", "vy_mps",
                  "cov_xx", "cov_xy", "cov_yy", "cov_vxvx", "cov_vxvy", "cov_vyvy",
                  "confirmed", "coasting", "n_points", "doppler_mps", "doppler_spread_mps",
                  "cov_xvx", "cov_xvy", "cov_yvx", "cov_yvy")
#: The optional point column whose per-object median and sample standard deviation the tracks
#: carry as ``doppler_mps`` and ``doppler_spread_mps``: the ego-motion-compensated radial speed
#: of a point (measured radial speed minus the one a static point at its angle would show, m/s;
#: blindspot.synth.driving_measurement).
DOPPLER_COLUMN = "velocity_over_ground_mps"
#: Optional point columns: the sensor's position in the points' frame of reference at the
#: point's frame (m; a moving radar's world position, the same on every row of a frame), the
#: origin of the line of sight of the Doppler gate (``tracker.doppler_std_mps``) and of the
#: field of view's bearings (``tracker.field_of_view_deg``). Without them the sensor is at the
#: origin; the heading column needs them.
SENSOR_COLUMNS = ("sensor_x_m", "sensor_y_m")
#: Optional point column: the sensor's boresight heading at the point's frame (deg, the driving
#: scenes' ego yaw convention: 0 looks along +y, counter-clockwise positive, so the boresight is
#: (-sin h, cos h)), the axis of ``tracker.field_of_view_deg``. Without it the field of view
#: deletes no track (recordings differ in the axis their sensor looks along).
SENSOR_HEADING_COLUMN = "sensor_heading_deg"

_EPOCH = dt.datetime(2000, 1, 1)
#: The largest |time_s| taken for seconds: 1e10 s is the year 2286 as a Unix time; larger stamps
#: are epoch milliseconds (1.7e12 today) or nanoseconds (1.7e18), refused with that hint.
MAX_TIME_S = 1e10


class TrackingError(ValueError):
    """Points given to the tracker are not what it expects (missing column, bad type, time
    running backwards)."""


def _who(source: str) -> str:
    """The start of a TrackingError: ``track_points`` and, when given, the points' file."""
    return f"track_points ({source})" if source else "track_points"


def _check_points(points: pd.DataFrame, source: str = "") -> bool:
    who = _who(source)
    if not isinstance(points, pd.DataFrame):
        raise TrackingError(f"{who}: points must be a pandas DataFrame; found "
                            f"{type(points).__name__}")
    check_columns(points, INPUT_COLUMNS, "points", error=TrackingError, who=who,
                  note=f"expected {list(INPUT_COLUMNS)} (+ optional group, velocity_mps); "
                       f"found {list(points.columns)}")
    for c in ("frame", "time_s"):   # null (NA, None, NaN) before any dtype or order test
        null = points[c].isna().to_numpy(bool)
        if null.any():
            first = points.index[int(np.argmax(null))]
            raise TrackingError(f"{who}: column {c!r} holds {int(null.sum())} null (missing) "
                                f"value(s) of {len(null)}, first at row {first!r}; every point "
                                f"needs its frame id and time")
    if not pd.api.types.is_integer_dtype(points["frame"]):
        raise TrackingError(f"{who}: column 'frame' must hold integers; found dtype "
                            f"{points['frame'].dtype}")
    for c in ("time_s", "x_m", "y_m"):
        _check_numeric(points, c, who)
    t = points["time_s"].to_numpy(float)
    if not np.isfinite(t).all():
        raise TrackingError(f"{who}: column 'time_s' holds infinite values")
    if len(t) and np.abs(t).max() > MAX_TIME_S:
        big = float(t[int(np.argmax(np.abs(t)))])
        raise TrackingError(f"{who}: column 'time_s' must be in seconds; found {big!r}, beyond "
                            f"{MAX_TIME_S:g} s (the year 2286 as a Unix time): epoch "
                            f"milliseconds (divide by 1e3) or nanoseconds (by 1e9)?")
    xy = points[["x_m", "y_m"]].to_numpy(float)
    if np.isinf(xy).any():
        raise TrackingError("track_points: columns x_m/y_m hold infinite values (NaN marks a "
                            "frame without points)")
    if (np.isnan(xy[:, 0]) != np.isnan(xy[:, 1])).any():
        raise TrackingError("track_points: x_m and y_m must be NaN together (a frame without "
                            "points); found rows with only one of them NaN")
    return "group" in points.columns


def _check_numeric(points: pd.DataFrame, column: str, who: str = "track_points") -> None:
    v = points[column]
    if not pd.api.types.is_numeric_dtype(v) or pd.api.types.is_bool_dtype(v):
        raise TrackingError(f"{who}: column {column!r} must be numeric; found dtype "
                            f"{v.dtype}")


def _check_poses(points: pd.DataFrame, keys: list[str], frames: pd.DataFrame,
                 pose_cols: list[str], every_frame: bool) -> None:
    """The sensor pose columns present (:data:`SENSOR_COLUMNS`, :data:`SENSOR_HEADING_COLUMN`;
    at least one): both position columns, numeric, one value per frame (``frames``: one row per
    frame, sorted by ``keys``) and finite on every frame with a point (the Doppler's line of
    sight) or, with ``every_frame`` (the field of view applied), on every frame, a frame
    without points included (its coasting tracks are tested). Raises TrackingError naming the
    column."""
    missing = [c for c in SENSOR_COLUMNS if c not in pose_cols]
    if missing:
        raise TrackingError(f"track_points: points hold {pose_cols} but not {missing}; the "
                            f"sensor's pose needs both of {list(SENSOR_COLUMNS)}")
    need = (np.ones(len(frames), bool) if every_frame
            else points.groupby(keys, sort=True).x_m.count().to_numpy() > 0)
    for c in pose_cols:
        _check_numeric(points, c)
        bad = ~np.isfinite(frames[c].to_numpy(float)) & need
        if bad.any():
            where = "every frame" if every_frame else "every frame with a point"
            raise TrackingError(f"track_points: column {c!r} is NaN or infinite at "
                                f"{int(bad.sum())} of {int(need.sum())} frames (first: frame "
                                f"{int(frames['frame'].iloc[np.flatnonzero(bad)[0]])}); the "
                                f"sensor's pose is needed on {where}")
    varies = points.groupby(keys, sort=False)[pose_cols].nunique().max()
    if (varies > 1).any():
        c = varies.index[int(np.argmax(varies.to_numpy() > 1))]
        raise TrackingError(f"track_points: column {c!r} takes {int(varies[c])} values within "
                            "one frame; the sensor has one pose per frame")


def _check_config(config: TrackerConfig, who: str) -> None:
    if not isinstance(config, TrackerConfig):
        raise TrackingError(f"{who}: config: expected a TrackerConfig (the tracker group), "
                            f"found {type(config).__name__}")


def cluster_points(points: pd.DataFrame, config: TrackerConfig) -> pd.DataFrame:
    """Objects of each frame: DBSCAN clusters of its points, as centroids.

    One DBSCAN call over every frame of every group: each point gets a third coordinate
    ``4 * eps * k`` with ``k`` the index of its (group, frame), so points of different frames are
    never neighbours and the clusters equal those of one DBSCAN per frame.

    Args:
        points: rows of ``frame`` (int), ``time_s``, ``x_m``, ``y_m`` (m), optional ``group``;
            rows with NaN x_m/y_m mark a frame observed without points.
        config: ``cluster_eps_m`` and ``cluster_min_samples`` are read.

    Returns:
        DataFrame with one row per object: (``group``), ``frame``, ``time_s``, ``x_m``, ``y_m``
        (centroid, m), ``n_points``. Points DBSCAN labels noise are dropped.

    Raises:
        TrackingError: as :func:`track_points`.
    """
    has_group = _check_points(points)
    _check_config(config, "cluster_points")
    keys = (["group"] if has_group else []) + ["frame"]
    return _centroids(_labelled(points, keys, config), keys)


def label_objects(points: pd.DataFrame, config: TrackerConfig) -> pd.Series:
    """(N,) int per row of ``points`` (as :func:`cluster_points`): the object (DBSCAN cluster,
    a number unique over every frame and group) the tracker makes of the point, -1 for a point
    DBSCAN calls noise or one without coordinates; index that of ``points``. The points of one
    object are what one track row's ``n_points``, ``doppler_mps`` and ``doppler_spread_mps``
    summarise. Raises TrackingError as :func:`track_points`."""
    has_group = _check_points(points)
    _check_config(config, "label_objects")
    keys = (["group"] if has_group else []) + ["frame"]
    kept = _labelled(points.reset_index(drop=True), keys, config)["_label"]
    out = np.full(len(points), -1, np.int64)
    out[kept.index.to_numpy()] = kept.to_numpy()
    return pd.Series(out, index=points.index)


def _labelled(points: pd.DataFrame, keys: list[str], config: TrackerConfig) -> pd.DataFrame:
    """The points with coordinates that DBSCAN keeps, with their cluster label ``_label``
    (unique over all frames and groups)."""
    valid = points.dropna(subset=["x_m", "y_m"])
    cols = keys + ["time_s", "x_m", "y_m"]
    if DOPPLER_COLUMN in valid.columns:
        cols.append(DOPPLER_COLUMN)
    if valid.empty:
        return valid[cols].assign(_label=np.empty(0, np.int64))
    k = valid.groupby(keys, sort=False).ngroup().to_numpy(float)
    eps = config.cluster_eps_m
    feats = np.column_stack([valid["x_m"].to_numpy(float), valid["y_m"].to_numpy(float),
                             4.0 * eps * k])
    labels = DBSCAN(eps=eps, min_samples=config.cluster_min_samples).fit_predict(feats)
    keep = labels >= 0
    return valid.loc[keep, cols].assign(_label=labels[keep])


def _centroids(labelled: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    return (labelled.groupby(keys + ["_label"], sort=True)
            .agg(time_s=("time_s", "first"), n_points=("x_m", "size"),
                 x_m=("x_m", "mean"), y_m=("y_m", "mean"))
            .reset_index().drop(columns="_label"))[keys + ["time_s", "n_points", "x_m", "y_m"]]


def _cached_cv_model(q: float, damping: float = 0.0):
    """Stone Soup's two-axis constant-velocity model with F and Q memoised per time step.

    ``CombinedLinearGaussianTransitionModel`` rebuilds both with ``scipy.linalg.block_diag`` on
    every call (about 0.7 ms per prediction on this machine, most of the tracker's time); frames
    come at a few distinct intervals, so each is built once. Values are Stone Soup's own
    (continuous white-noise acceleration, Bar-Shalom et al. 2001, eq. 6.2.2-12); with
    ``damping`` K > 0, Stone Soup's ``OrnsteinUhlenbeck`` model instead (velocity decays as
    exp(-K t) between measurements: a pedestrian who stops)."""
    from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                    ConstantVelocity, OrnsteinUhlenbeck)

    class CachedCombinedCV(CombinedLinearGaussianTransitionModel):
        def matrix(self, **kwargs):
            key = ("F", kwargs.get("time_interval"))
            if key not in _cache:
                _cache[key] = super().matrix(**kwargs)
            return _cache[key]

        def covar(self, **kwargs):
            key = ("Q", kwargs.get("time_interval"))
            if key not in _cache:
                _cache[key] = super().covar(**kwargs)
            return _cache[key]

    _cache: dict = {}
    if damping > 0:
        return CachedCombinedCV([OrnsteinUhlenbeck(q, damping), OrnsteinUhlenbeck(q, damping)])
    return CachedCombinedCV([ConstantVelocity(q), ConstantVelocity(q)])


def _numpy_kalman(transition_model, measurement_model):
    """Stone Soup's ``KalmanPredictor`` and ``KalmanUpdater`` with their arithmetic on plain
    numpy arrays: the stock classes spend most of their time in the ``__array_ufunc__`` of Stone
    Soup's ``StateVector``/``Matrix`` subclasses and in ``from_state`` copies (about 1 ms per
    track and frame on this machine, ``benchmarks/bench_tracking.py --profile``). Same equations
    (Bar-Shalom et al. 2001, sec. 5.2.3), same input and output types; tests/track check them
    against the stock classes.

    Returns (predictor, updater): the arithmetic is :mod:`blindspot.kalman`'s one-step
    functions, the one Kalman filter of blindspot.
    """
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.array import CovarianceMatrix, StateVector
    from stonesoup.types.prediction import (GaussianMeasurementPrediction,
                                            GaussianStatePrediction)
    from stonesoup.types.update import GaussianStateUpdate
    from stonesoup.updater.kalman import KalmanUpdater

    from blindspot import kalman

    H = np.asarray(measurement_model.matrix(), float)
    R = np.asarray(measurement_model.covar(), float)

    class NumpyKalmanPredictor(KalmanPredictor):
        def predict(self, prior, timestamp=None, **kwargs):
            dt = timestamp - prior.timestamp
            F = np.asarray(self.transition_model.matrix(time_interval=dt), float)
            Q = np.asarray(self.transition_model.covar(time_interval=dt), float)
            x, P = kalman.predict(np.asarray(prior.state_vector, float),
                                  np.asarray(prior.covar, float), F, Q)
            return GaussianStatePrediction(StateVector(x), CovarianceMatrix(P),
                                           timestamp=timestamp,
                                           transition_model=self.transition_model)

    class NumpyKalmanUpdater(KalmanUpdater):
        @staticmethod
        def measurement_moments(predicted_state, measurement_noise=True):
            """(H x (2, 1), S = H P H^T + R (2, 2), P H^T (4, 2)) of a predicted state, plain
            arrays: what a gate needs, without building the Stone Soup prediction object."""
            return kalman.measurement_moments(np.asarray(predicted_state.state_vector, float),
                                              np.asarray(predicted_state.covar, float), H,
                                              R if measurement_noise else 0.0)

        @staticmethod
        def measurement_prediction(predicted_state, moments):
            """The ``GaussianMeasurementPrediction`` of :meth:`measurement_moments`."""
            zhat, S, PHt = moments
            return GaussianMeasurementPrediction(StateVector(zhat), CovarianceMatrix(S),
                                                 timestamp=predicted_state.timestamp,
                                                 cross_covar=CovarianceMatrix(PHt))

        def predict_measurement(self, predicted_state, measurement_model=None,
                                measurement_noise=True, **kwargs):
            return self.measurement_prediction(
                predicted_state, self.measurement_moments(predicted_state, measurement_noise))

        def update(self, hypothesis, **kwargs):
            pred = hypothesis.prediction
            mp = hypothesis.measurement_prediction
            if mp is None:
                mp = hypothesis.measurement_prediction = self.predict_measurement(pred)
            x, P = kalman.update(np.asarray(pred.state_vector, float),
                                 np.asarray(pred.covar, float),
                                 np.asarray(hypothesis.measurement.state_vector, float),
                                 np.asarray(mp.state_vector, float),
                                 np.asarray(mp.covar, float), np.asarray(mp.cross_covar, float))
            return GaussianStateUpdate(StateVector(x), CovarianceMatrix(P),
                                       hypothesis=hypothesis,
                                       timestamp=hypothesis.measurement.timestamp)

    return (NumpyKalmanPredictor(transition_model),
            NumpyKalmanUpdater(measurement_model, force_symmetric_covariance=True))


def _equivalent_2dof(d2: np.ndarray) -> np.ndarray:
    """The chi-square (2 dof) value with the tail probability that ``d2`` has under 3 dof:
    ``-2 ln(sf_3(x))`` with ``sf_3(x) = erfc(sqrt(x / 2)) + sqrt(2 x / pi) exp(-x / 2)``
    (closed forms of both tails; Abramowitz & Stegun 26.4.4-26.4.5). (...) -> (...), inf
    where the 3-dof tail underflows."""
    from scipy.special import erfc

    x = np.asarray(d2, dtype=float)
    sf = erfc(np.sqrt(x / 2)) + np.sqrt(2 * x / np.pi) * np.exp(-x / 2)
    with np.errstate(divide="ignore"):
        return -2.0 * np.log(np.minimum(sf, 1.0))


def _gated_hypothesiser(predictor, updater, gate: float, doppler_std_mps: float | None = None):
    """Stone Soup's ``DistanceHypothesiser`` with the ``Mahalanobis`` measure, gating every
    detection of a frame in one numpy expression: d^2 = v^T S^-1 v for the innovations v of all
    detections against the track's one measurement prediction (every detection shares the
    measurement model). Returns the same hypotheses as the parent class, which evaluates the
    measure detection by detection (tests/track/test_tracker.py). ``updater`` must be the one of
    :func:`_numpy_kalman` (its ``measurement_moments`` give S without building the Stone Soup
    measurement prediction, which only a track that gates a detection gets).

    With ``doppler_std_mps``, a detection whose metadata carries a finite ``doppler_mps`` (the
    median ego-motion-compensated radial speed of its n points) and ``sensor_xy`` adds the
    Doppler innovation: the track's predicted velocity v along the unit line of sight u from
    the sensor to the detection predicts u.v with variance u^T P_v u, the measurement's own
    variance is doppler_std^2 / n, and

        d3^2 = v^T S^-1 v + (doppler - u.v)^2 / (doppler_std^2 / n + u^T P_v u),

    a chi-square variable of 3 degrees of freedom (the position and Doppler innovations taken
    as independent, which drops their cross-covariance through the predicted state; the median
    of n points taken as their mean, so ``doppler_std`` is an empirical spread, as in the
    moving test of blindspot.safety.predict). It is mapped to the 2-dof distance of the same
    tail probability, ``chi2_2.isf(chi2_3.sf(d3^2))`` (:func:`_equivalent_2dof`), so the gate
    and the missed-detection cost keep their 2-dof ``gate_probability`` meaning and a
    detection with a Doppler value competes on the same scale as one without. A range-rate
    gate in the manner of Blackman & Popoli 1999 (sec. 6.2): a clutter track on a parked
    car's face, sliding at the ego's speed, predicts a radial speed that a crossing child's
    Doppler contradicts, so it cannot take the child's detection; nor can it keep its own
    static points. Detections without a Doppler value gate on position alone."""
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.measures import Mahalanobis
    from stonesoup.types.detection import MissedDetection
    from stonesoup.types.hypothesis import SingleDistanceHypothesis
    from stonesoup.types.multihypothesis import MultipleHypothesis

    class GatedDistanceHypothesiser(DistanceHypothesiser):
        # (detections, their list, (2, n) positions, their Doppler terms or None)
        _last: tuple = (None, [], None, None)

        def _stacked(self, detections):
            """The detections as a list, their (2, n) positions and, with the Doppler gate,
            their Doppler terms (:meth:`_doppler_terms`), built once per set: the associator
            passes one set object to every track of a frame's stage, so the stacking (a quarter
            of the gating's time) is not redone per track. The set is held, so its id cannot be
            reused while cached."""
            if self._last[0] is not detections:
                dets = list(detections)
                z = np.hstack([np.asarray(d.state_vector, float) for d in dets])
                terms = None if doppler_std_mps is None else self._doppler_terms(dets, z)
                self._last = (detections, dets, z, terms)
            return self._last[1:]

        @staticmethod
        def _doppler_terms(dets, z):
            """(median radial speed (n,), point count (n,) >= 1, unit line of sight (2, n) from
            the sensor, has a Doppler value (n,)) of the detections ``dets`` at positions z."""
            dop = np.array([d.metadata.get("doppler_mps", np.nan) for d in dets], float)
            n_pts = np.array([d.metadata.get("n_points", 1) for d in dets], float)
            sensor = np.array([d.metadata.get("sensor_xy", (0.0, 0.0)) for d in dets], float).T
            los = z - sensor
            rng = np.hypot(los[0], los[1])
            u = los / np.where(rng > 0, rng, 1.0)
            return dop, np.maximum(n_pts, 1.0), u, np.isfinite(dop) & (rng > 0)

        def hypothesise(self, track, detections, timestamp, **kwargs):
            prediction = self.predictor.predict(track, timestamp=timestamp)
            hypotheses = [SingleDistanceHypothesis(
                prediction, MissedDetection(timestamp=timestamp), self.missed_distance)]
            if detections:
                dets, z, terms = self._stacked(detections)
                moments = self.updater.measurement_moments(prediction)
                v = z - moments[0]
                # v^T S^-1 v in closed form for the 2 x 2 S (a LAPACK solve per track and frame
                # was 7 % of the tracker's time on the driving clouds)
                (a, b), (c, d) = moments[1]
                d2 = (d * v[0] ** 2 - (b + c) * v[0] * v[1] + a * v[1] ** 2) / (a * d - b * c)
                dist = np.sqrt(d2 if terms is None else self._with_doppler(prediction, d2, terms))
                gated = np.flatnonzero(dist < self.missed_distance)
                # the measurement prediction object only for a track that gates a detection
                # (about half of the driving scenes' clutter tracks coast on a frame)
                mp = (self.updater.measurement_prediction(prediction, moments) if len(gated)
                      else None)
                for j in gated:
                    hypotheses.append(SingleDistanceHypothesis(prediction, dets[j],
                                                               float(dist[j]), mp))
            return MultipleHypothesis(sorted(hypotheses, reverse=True))

        @staticmethod
        def _with_doppler(prediction, d2, terms):
            """(n,) squared distances on the 2-dof scale with the Doppler innovation where a
            detection has one (class docstring); ``terms`` from :meth:`_doppler_terms`."""
            dop, n_pts, u, has = terms
            sv = np.asarray(prediction.state_vector, float).ravel()
            pc = np.asarray(prediction.covar, float)
            uv = u[0] * sv[1] + u[1] * sv[3]
            pu = pc[1, 1] * u[0] ** 2 + 2 * pc[1, 3] * u[0] * u[1] + pc[3, 3] * u[1] ** 2
            r2 = (np.nan_to_num(dop) - uv) ** 2 / (doppler_std_mps ** 2 / n_pts + pu)
            return np.where(has, _equivalent_2dof(d2 + np.where(has, r2, 0.0)), d2)

    return GatedDistanceHypothesiser(predictor, updater, measure=Mahalanobis(),
                                     missed_distance=gate)


def _linear_initiator(prior, measurement_model, doppler_std_mps: float | None = None,
                      along_std_mps: float | None = None):
    """Stone Soup's ``SimpleMeasurementInitiator`` for one linear measurement model, with the
    model's pseudo-inverse and the initial covariance computed once instead of per detection
    (1.4 ms per new track in the parent class on this machine). Same state and covariance:
    x0 = prior with the measured dimensions replaced by H^+ z, P0 = H^+ R H^+T + prior covariance
    outside the measured dimensions.

    With ``doppler_std_mps`` (``tracker.init_doppler_std_mps``), a detection whose metadata
    carries a finite ``doppler_mps`` d (the median ego-motion-compensated radial speed of its n
    points) and ``sensor_xy`` starts its track with the velocity that the Doppler and the
    geometry allow instead of the prior's zero: the radial speed is one linear measurement of
    the velocity, d = u.v + e, e ~ N(0, doppler_std^2 / n), along the unit line of sight u from
    the sensor to the detection, so the Kalman update of the velocity prior N(0, s0^2 I)
    (s0 = ``init_velocity_std_mps``) by it gives

        v0 = s0^2 u d / (s0^2 + doppler_std^2 / n),
        P_v0 = s0^2 I - s0^4 u u^T / (s0^2 + doppler_std^2 / n):

    the radial part known to the Doppler's accuracy, the tangential part still the prior's
    (Bar-Shalom, Li & Kirubarajan 2001, sec. 5.2.3, one scalar measurement). A static object
    (d ~ 0) starts near zero velocity as before; a child stepping out with a radial component
    starts moving. The state order is [x, vx, y, vy].

    With ``along_std_mps`` (``tracker.init_doppler_along_std_mps``) and the detection's
    ``sensor_heading_rad`` (the boresight (-sin h, cos h): along the road for a car's radar),
    the velocity prior of that update is s_along along the boresight and s0 across it: the
    context prior of a pedestrian stepping out from between parked cars, who crosses the road
    rather than walks along it, so the Doppler's radial speed (mostly across the road for an
    object beside the lane) fixes the crossing speed. A detection without a heading keeps the
    isotropic prior."""
    from stonesoup.initiator.simple import SimpleMeasurementInitiator
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.track import Track
    from stonesoup.types.update import GaussianStateUpdate

    h_pinv = np.linalg.pinv(measurement_model.matrix())
    mapped = list(measurement_model.mapping)
    base = np.asarray(prior.state_vector, float).copy()
    base[mapped, :] = 0.0
    covar0 = np.asarray(prior.covar, float).copy()
    covar0[mapped, :] = 0.0
    covar0[:, mapped] = 0.0
    covar0 = covar0 + h_pinv @ measurement_model.covar() @ h_pinv.T
    vel = [i for i in range(covar0.shape[0]) if i not in mapped]     # [1, 3]: vx, vy

    def start(z, meta):
        """(x0 (4, 1), P0 (4, 4)) of one detection at z (2, 1) with metadata ``meta`` (class
        docstring)."""
        x0 = base + h_pinv @ z
        if doppler_std_mps is None:
            return x0, covar0.copy()
        d = float(meta.get("doppler_mps", np.nan))
        los = np.asarray(z, float).ravel() - np.asarray(
            meta.get("sensor_xy", (0.0, 0.0)), float)
        rng = float(np.hypot(*los))
        if not (np.isfinite(d) and rng > 0):
            return x0, covar0.copy()
        u = los / rng
        pv = covar0[np.ix_(vel, vel)]
        h = meta.get("sensor_heading_rad")
        if along_std_mps is not None and h is not None:
            b = np.array([-np.sin(h), np.cos(h)])               # boresight: along the road
            a = np.array([b[1], -b[0]])                         # across it
            pv = pv[0, 0] * np.outer(a, a) + along_std_mps ** 2 * np.outer(b, b)
        pu = pv @ u
        s = float(u @ pu) + doppler_std_mps ** 2 / max(int(meta.get("n_points", 1)), 1)
        gain = pu / s
        x0 = np.asarray(x0, float).copy()
        x0[vel, 0] = x0[vel, 0] + gain * (d - float(u @ x0[vel, 0]))
        p0 = covar0.copy()
        p0[np.ix_(vel, vel)] = pv - np.outer(gain, pu)
        return x0, p0

    class LinearMeasurementInitiator(SimpleMeasurementInitiator):
        def initiate(self, detections, timestamp, **kwargs):
            out = set()
            for det in detections:
                x0, p0 = self.start(det.state_vector, det.metadata)
                out.add(Track([GaussianStateUpdate(x0, p0, SingleHypothesis(None, det),
                                                   timestamp=det.timestamp)]))
            return out

    initiator = LinearMeasurementInitiator(prior, measurement_model)
    initiator.start = start          # the fast GNN path starts a track from arrays
    return initiator


@dataclass
class _Parts:
    """Stone Soup components of one tracker, built once from the config."""

    measurement_model: object
    predictor: object
    updater: object
    associator: object
    initiator: object
    jpda: bool
    gate: float = np.inf                  # GNN: the Mahalanobis gate (the missed distance)
    doppler_std_mps: float | None = None  # GNN: the Doppler gate's point spread (None: off)
    fast: bool = True                     # GNN: the vectorised step (:func:`_gnn_stage`)


def _parts(config: TrackerConfig) -> _Parts:
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import JPDA
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.state import GaussianState

    transition = _cached_cv_model(config.process_noise_m2ps3, config.velocity_damping_per_s)
    r = config.measurement_noise_m ** 2
    measurement_model = LinearGaussian(ndim_state=4, mapping=(0, 2),
                                       noise_covar=np.diag([r, r]))
    predictor, updater = _numpy_kalman(transition, measurement_model)
    if config.association == "gnn":
        gate = float(np.sqrt(chi2.ppf(config.gate_probability, df=2)))
        hypothesiser = _gated_hypothesiser(predictor, updater, gate, config.doppler_std_mps)
        associator = GNNWith2DAssignment(hypothesiser)
    else:
        hypothesiser = PDAHypothesiser(predictor, updater,
                                       clutter_spatial_density=config.clutter_density_per_m2,
                                       prob_detect=config.detection_probability,
                                       prob_gate=config.gate_probability)
        associator = JPDA(hypothesiser)
    v2 = config.init_velocity_std_mps ** 2
    prior = GaussianState(np.zeros((4, 1)), np.diag([0.0, v2, 0.0, v2]))
    initiator = _linear_initiator(prior, measurement_model, config.init_doppler_std_mps,
                                  config.init_doppler_along_std_mps)
    if config.association == "gnn":
        return _Parts(measurement_model, predictor, updater, associator, initiator, False,
                      gate, config.doppler_std_mps)
    return _Parts(measurement_model, predictor, updater, associator, initiator, True)


@dataclass
class _Book:
    """Track management beside a Stone Soup track: its id and its hit/miss history."""

    track_id: int
    hits: list[bool] = field(default_factory=list)
    confirmed: bool = False
    born_s: float = 0.0          # time of its first detection (s, the group's clock)
    last_hit_s: float = 0.0      # time of its last detection
    # with a Doppler notch: stopped there (blindspot.track.stopped) since ``stopped_s`` (s),
    # held at ``held`` (x (4,), P (4, 4), velocity zero); ``seen``: its state at its last
    # detection
    stopped: bool = False
    stopped_s: float = 0.0
    held: tuple | None = None
    seen: tuple | None = None
    # (points, median ego-compensated radial speed) of each hit's object, oldest first
    dopplers: list[tuple[int, float]] = field(default_factory=list)


def _first_stage(book: _Book, t: float, silent_first_s: float | None) -> bool:
    """Whether a track is associated in the first stage at time ``t`` (s, the group's clock):
    confirmed and, with ``silent_first_s``, its last hit at most that long ago (the time of
    ``tracker.priority_max_coast_frames`` missed frames and the hit's own, plus half a frame,
    so frames absent from the points count as the empty frames they replace, as for
    deletion)."""
    return book.confirmed and (silent_first_s is None or t - book.last_hit_s <= silent_first_s)


def _doppler_confirms(book: _Book, config: TrackerConfig, window: int) -> bool:
    """A tentative track confirms early, on its second consecutive hit, when the radial speeds
    of its objects say "moving" (``tracker.doppler_confirm_log_ratio``; null: never): their
    :func:`~blindspot.track.moving.doppler_motion_log_ratio` over its hits (point spread
    ``tracker.moving.doppler_std_mps``, the last ``window`` hits: ``confirm_n`` at the group's
    frame period) reaches that. A static object's
    compensated Doppler is ~0, so the parked cars' edges, the kerb and zero-Doppler multipath
    keep the M-of-N rule; a walker with a radial component confirms in two frames."""
    if (config.doppler_confirm_log_ratio is None or config.moving is None
            or len(book.hits) < 2 or not all(book.hits[-2:])):
        return False
    n, d = np.array(book.dopplers[-window:], float).T
    return bool(doppler_motion_log_ratio(n, d, config.moving.doppler_std_mps)
                >= config.doppler_confirm_log_ratio)


def _jpda_posterior(track, multihypothesis, updater):
    """Gaussian-mixture reduction of the JPDA hypotheses of one track (Stone Soup's JPDA
    tutorial; Bar-Shalom, Daum & Huang 2009). Returns (state, hit): hit when the hypotheses
    with a detection carry more than half the probability."""
    from stonesoup.functions import gm_reduce_single
    from stonesoup.types.array import StateVectors
    from stonesoup.types.prediction import GaussianStatePrediction
    from stonesoup.types.update import GaussianStateUpdate

    states, weights, p_detected = [], [], 0.0
    for hyp in multihypothesis:
        p = float(hyp.probability)
        if hyp:
            states.append(updater.update(hyp))
            p_detected += p
        else:
            states.append(hyp.prediction)
        weights.append(p)
    means = StateVectors([s.state_vector for s in states])
    covars = np.stack([s.covar for s in states], axis=2)
    mean, covar = gm_reduce_single(means, covars, np.asarray(weights))
    ts = multihypothesis[0].prediction.timestamp
    if p_detected > 0.5:
        return GaussianStateUpdate(mean, covar, multihypothesis, ts), True
    return GaussianStatePrediction(mean, covar, timestamp=ts), False


def _range_rate_update(x: np.ndarray, P: np.ndarray, doppler_mps: np.ndarray,
                       n_points: np.ndarray, sensor_xy, doppler_std_mps: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """The states (x (K, 4), P (K, 4, 4), [x, vx, y, vy]) after the range-rate measurement of
    the object that updated each (``tracker.doppler_update_std_mps``): its median
    ego-motion-compensated radial speed d of n points, d = u.v + e, e ~ N(0, doppler_std^2 / n),
    u the unit line of sight from the sensor (``sensor_xy``) to the updated position (held
    fixed: the extended Kalman filter's linearisation, whose neglected term is the position's
    spread across the line of sight: a few cm of a 10 m range), as one scalar Kalman update of the whole state
    (positions move with their correlation to the velocity; Bar-Shalom, Li & Kirubarajan 2001,
    sec. 5.2 and 10.3). Rows without a finite Doppler, or at the sensor, keep their state."""
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    los = x[:, [0, 2]] - np.asarray(sensor_xy, float)[None, :]
    rng = np.hypot(los[:, 0], los[:, 1])
    d = np.asarray(doppler_mps, float)
    ok = np.isfinite(d) & (rng > 0)
    if not ok.any():
        return x, P
    h = np.zeros((len(x), 4))
    h[:, 1], h[:, 3] = (los / np.where(rng > 0, rng, 1.0)[:, None]).T
    ph = np.einsum("kij,kj->ki", P, h)
    s = np.einsum("ki,ki->k", h, ph) + doppler_std_mps ** 2 / np.maximum(
        np.asarray(n_points, float), 1.0)
    k = ph / s[:, None]
    innov = np.where(ok, np.nan_to_num(d) - np.einsum("ki,ki->k", h, x), 0.0)
    x_new = x + k * innov[:, None]
    p_new = P - k[:, :, None] * ph[:, None, :]
    p_new = 0.5 * (p_new + np.swapaxes(p_new, 1, 2))
    return np.where(ok[:, None], x_new, x), np.where(ok[:, None, None], p_new, P)


class _Track:
    """A track of the vectorised GNN step (:func:`_gnn_stage`): its filtered state only, x (4,)
    and P (4, 4) (a Stone Soup ``Track`` keeps every state; the tracker reads the last)."""

    __slots__ = ("x", "P")

    def __init__(self, x: np.ndarray, P: np.ndarray):
        self.x, self.P = x, P


def _state_arrays(track) -> tuple[np.ndarray, np.ndarray]:
    """(x (4,), P (4, 4)) of the last state of a :class:`_Track` or a Stone Soup track."""
    if isinstance(track, _Track):
        return track.x, track.P
    return (np.asarray(track.state.state_vector, float).ravel(),
            np.asarray(track.state.covar, float))


def _gnn_stage(tracks: list, z: np.ndarray, free: np.ndarray, F: np.ndarray, Q: np.ndarray,
               R: np.ndarray, gate: float, doppler: tuple | None, doppler_std_mps: float | None
               ) -> tuple[np.ndarray, np.ndarray]:
    """One association stage of the GNN tracker on arrays: what Stone Soup's
    ``GNNWith2DAssignment`` with the gated Mahalanobis hypothesiser
    (:func:`_gated_hypothesiser`) and the Kalman steps of :func:`_numpy_kalman` give, without a
    Python object per track, hypothesis or detection (those cost about 0.3 ms per track and
    frame, most of the tracker's time on the driving scenes' hundreds of static objects).

    The tracks (all stepped at the previous frame, so one F and Q) are predicted together
    (:func:`blindspot.kalman.predict_covariance` on the stack), the distances of every track
    to every free detection are one (T, D) array with the hypothesiser's formulas (the
    Doppler term of :meth:`_with_doppler` included), a track gating no detection coasts, and
    the tracks gating one are assigned by scipy's ``linear_sum_assignment`` on Stone Soup's
    cost matrix (distances within the gate, one missed-detection column per track at the
    gate's distance). Matched tracks get :func:`blindspot.kalman.update`. Tested byte-equal to
    the Stone Soup path (tests/track/test_fast_gnn.py).

    Args:
        tracks: the stage's :class:`_Track` objects (T); their x and P are replaced.
        z: (D, 2) the frame's object positions; free: (D,) bool, those no earlier stage took.
        F, Q: the transition over the frame interval; R: (2, 2) the measurement noise.
        gate: the gate on the distance (sqrt of the 2-dof squared distance).
        doppler: None or the detections' Doppler terms (as the hypothesiser's
            ``_doppler_terms``: median radial speed (D,), point count (D,) >= 1, unit line of
            sight (2, D) from the sensor, has a value (D,)); doppler_std_mps: the Doppler gate's
            point spread.

    Returns:
        (hit (T,) bool, detection index (T,) int, -1 for a miss).
    """
    from scipy.optimize import linear_sum_assignment

    from blindspot import kalman

    n_t = len(tracks)
    x = np.stack([tr.x for tr in tracks])                                  # (T, 4)
    P = np.stack([tr.P for tr in tracks])                                  # (T, 4, 4)
    xp = (F @ x[:, :, None])[:, :, 0]           # F x per track (the same bytes as one by one)
    Pp = kalman.predict_covariance(P, F, Q)
    det = np.full(n_t, -1, np.int64)
    cols = np.flatnonzero(free)
    if cols.size:
        S = Pp[:, [0, 2]][:, :, [0, 2]] + R                   # H P H^T + R, H = [e0, e2]
        a, b, c, d = S[:, 0, 0, None], S[:, 0, 1, None], S[:, 1, 0, None], S[:, 1, 1, None]
        v0 = z[cols, 0][None, :] - xp[:, 0, None]
        v1 = z[cols, 1][None, :] - xp[:, 2, None]
        d2 = (d * v0 ** 2 - (b + c) * v0 * v1 + a * v1 ** 2) / (a * d - b * c)   # (T, D')
        if doppler is not None:
            dop, n_pts, u, has = (t[..., cols] for t in doppler)
            uv = u[0] * xp[:, 1, None] + u[1] * xp[:, 3, None]
            pu = (Pp[:, 1, 1, None] * u[0] ** 2 + 2 * Pp[:, 1, 3, None] * u[0] * u[1]
                  + Pp[:, 3, 3, None] * u[1] ** 2)
            r2 = (np.nan_to_num(dop) - uv) ** 2 / (doppler_std_mps ** 2 / n_pts + pu)
            d2 = np.where(has, _equivalent_2dof(d2 + np.where(has, r2, 0.0)), d2)
        dist = np.sqrt(d2)
        inside = dist < gate
        rows = np.flatnonzero(inside.any(axis=1))
        if rows.size:
            n_r = rows.size
            cost = np.full((n_r, cols.size + n_r), np.inf)
            cost[:, :cols.size] = np.where(inside[rows], dist[rows], np.inf)
            cost[np.arange(n_r), cols.size + np.arange(n_r)] = gate
            r_i, c_i = linear_sum_assignment(cost)
            took = c_i < cols.size
            det[rows[r_i[took]]] = cols[c_i[took]]
    hit = det >= 0
    h = np.flatnonzero(hit)
    if h.size:                          # the matched tracks' corrections, one stacked update
        ph = Pp[h]
        xu, Pu = kalman.update(xp[h, :, None], ph, z[det[h], :, None], xp[h][:, [0, 2], None],
                               ph[:, [0, 2]][:, :, [0, 2]] + R, ph[:, :, [0, 2]])
        xp[h], Pp[h] = xu[:, :, 0], Pu
    for tr, xi, Pi in zip(tracks, xp, Pp):
        tr.x, tr.P = xi, Pi
    return hit, det


def _set_state(track, x: np.ndarray, P: np.ndarray) -> None:
    """Replace the last state of a :class:`_Track` or a Stone Soup track (a copy of it with
    this mean and covariance, its type and timestamp kept)."""
    if isinstance(track, _Track):
        track.x, track.P = x, P
        return
    from stonesoup.types.array import CovarianceMatrix, StateVector

    state = copy.copy(track.state)
    state.state_vector = StateVector(np.asarray(x, float).reshape(-1, 1))
    state.covar = CovarianceMatrix(np.asarray(P, float))
    track[-1] = state


def _held_noise(parts: _Parts, gap: dt.timedelta, period: float) -> np.ndarray:
    """The process noise a stopped track is predicted with over a frame interval ``gap``: that of
    at most one frame period (``period`` s), however long the gap: a standing person does not
    diffuse, and one who walks off is met within a frame's reach."""
    step = min(gap, dt.timedelta(seconds=period)) if np.isfinite(period) else gap
    return np.asarray(parts.predictor.transition_model.covar(time_interval=step), float)


def _held_for(track, ts, prev_ts, period: float) -> None:
    """A stopped Stone Soup track's last state stamped at most one frame period before ``ts``,
    so the predictor's process noise spans that, as :func:`_held_noise` for the vectorised
    path."""
    if prev_ts is None or not np.isfinite(period):
        return
    state = copy.copy(track.state)
    state.timestamp = max(prev_ts, ts - dt.timedelta(seconds=period))
    track[-1] = state


def _silence_in_notch(live: dict, hit_now: dict, sensor_xy, min_speed: float,
                      config: TrackerConfig, partial: set) -> None:
    """After a frame's association, for a sensor with a Doppler notch
    (:mod:`blindspot.track.stopped`): a detected track is moving, and what was last seen of it
    is kept; a silent stopped track stays held where it stopped (the stopped mode: zero
    velocity, no process noise); each other silent confirmed track takes the frame's negative
    information (:func:`~blindspot.track.stopped.notch_update`) and coasts, except those in
    ``partial`` (JPDA: detections in its gate took part of its update)."""
    silent = []
    for tr, hit in hit_now.items():
        book = live[tr]
        if hit:
            book.seen, book.stopped, book.held = _state_arrays(tr), False, None
        elif book.stopped:
            _set_state(tr, *book.held)
        elif book.confirmed and tr not in partial:
            silent.append(tr)
    if silent:
        xs, ps = zip(*(_state_arrays(tr) for tr in silent))
        x, P = notch_update(np.stack(xs), np.stack(ps), sensor_xy, min_speed,
                            config.detection_probability)
        for tr, xi, pi in zip(silent, x, P):
            _set_state(tr, xi, pi)


def _ends_silence(track, book: _Book, t: float, min_speed: float | None,
                  config: TrackerConfig) -> bool:
    """A confirmed track silent longer than its coasting time, at time ``t`` (s): whether it is
    deleted (True) or, behind a Doppler notch, stopped and held where it was last detected
    (False) because what was last seen of it says it was stopping: its last object's radial
    speed inside the notch (:func:`~blindspot.track.stopped.seen_slowing`) and its velocity
    then consistent with standing (:func:`~blindspot.track.stopped.still`). A stopped track is
    deleted once held longer than ``tracker.max_stop_s``."""
    if book.stopped:
        return t - book.stopped_s > config.max_stop_s
    if min_speed is None or book.seen is None or not book.dopplers:
        return True
    n, d = book.dopplers[-1]
    if not (still(*book.seen)
            and seen_slowing(n, d, min_speed, config.moving.doppler_std_mps)):
        return True
    book.stopped, book.stopped_s = True, float(t)
    (x,), (P,) = held_state(book.seen[0][None], book.seen[1][None])
    book.held = (x, P)
    _set_state(track, *book.held)
    return False


def _objects(xy: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) centroids of the points (n, 2) of each label, in label order, and (k,) counts."""
    _, inverse, counts = np.unique(labels, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 2))
    np.add.at(sums, inverse, xy)
    return sums / counts[:, None], counts


def _track_group(labelled: pd.DataFrame, frames: pd.DataFrame, config: TrackerConfig,
                 parts: _Parts, min_speed: float | None = None) -> dict[str, list]:
    """Step the tracker through the frames of one group; return output columns as lists
    (``min_speed``: the sensor's minimum detectable radial speed, m/s, or None)."""
    from stonesoup.types.detection import Detection

    out = {c: [] for c in OUTPUT_COLUMNS}
    labelled = labelled.sort_values("frame", kind="stable")
    of = labelled["frame"].to_numpy()
    cut = np.flatnonzero(np.diff(of)) + 1
    starts = of[np.r_[0, cut]] if len(of) else []
    by_frame = dict(zip(starts, zip(np.split(labelled[["x_m", "y_m"]].to_numpy(float), cut),
                                    np.split(labelled["_label"].to_numpy(np.int64), cut))))
    # the sensor's position per frame (the Doppler gate's line of sight; origin without it)
    sensor_xy = (frames[list(SENSOR_COLUMNS)].to_numpy(float)
                 if all(c in frames.columns for c in SENSOR_COLUMNS)
                 else np.zeros((len(frames), 2)))
    no_points = (np.empty((0, 2)), np.empty(0, np.int64))
    # per object (label): the median ego-motion-compensated radial speed of its points and
    # their sample standard deviation (the micro-Doppler spread; NaN for one point)
    by_label = (labelled.groupby("_label")[DOPPLER_COLUMN].agg(["median", "std"])
                if DOPPLER_COLUMN in labelled.columns else None)
    # a frame's labels are looked up in the sorted label index (a pandas reindex per frame
    # cost more than the lookup); every label of a frame is in it
    dop_label = None if by_label is None else by_label.index.to_numpy()
    dop_value = None if by_label is None else by_label["median"].to_numpy(float)
    dop_spread = None if by_label is None else by_label["std"].to_numpy(float)
    # Deletion by elapsed time (Stone Soup's UpdateTimeDeleter): a confirmed track silent
    # longer than max_misses frame periods (plus half a period of timing jitter) is deleted
    # after a miss, and one silent longer than max_misses + 1 periods (the last frame at which
    # a frame-count rule could still update it) before it may take a detection; a tentative one
    # once its confirm_n frames' time has passed. The frame period is the group's median frame
    # interval, so frames absent from the points count as the empty frames they replace.
    times = frames["time_s"].to_numpy(float)
    t0 = float(times[0]) if len(times) else 0.0
    period = float(np.median(np.diff(times))) if len(times) > 1 else np.inf
    # the counts at this group's frame period (tracker.count_period_s)
    m, n, max_misses, k = config.counts_at(period)
    silent_after_miss_s = (max_misses + 0.5) * period
    silent_before_s = (max_misses + 1.5) * period
    tentative_s = (n - 0.5) * period
    silent_first_s = None if k is None else (k + 1.5) * period
    # the field of view's test per frame: the sensor's position, boresight and cos(half width);
    # a full circle deletes nothing (its cos(180 deg) = -1 would, by rounding, right behind)
    fov_cos = (None if config.field_of_view_deg is None or config.field_of_view_deg >= 360.0
               else np.cos(np.radians(config.field_of_view_deg / 2.0)))
    pose = (_frame_poses(frames) if fov_cos is not None and SENSOR_HEADING_COLUMN in frames
            else None)
    heading = (np.radians(frames[SENSOR_HEADING_COLUMN].to_numpy(float))
               if SENSOR_HEADING_COLUMN in frames else None)
    live: dict[object, _Book] = {}
    next_id = 0
    # GNN: the vectorised step on arrays (:func:`_gnn_stage`), Stone Soup's objects otherwise
    fast = parts.fast and not parts.jpda
    R_meas = np.asarray(parts.measurement_model.covar(), float)
    prev_ts = None
    for i_frame, (frame, t) in enumerate(zip(frames["frame"].to_numpy(),
                                             frames["time_s"].to_numpy(float))):
        # Stone Soup's timestamps on the group's own clock (from its first frame): any epoch
        # in seconds stays in datetime's range and keeps its microseconds
        ts = _EPOCH + dt.timedelta(seconds=float(t) - t0)
        # silent too long (no frames at all): deleted, or stopped behind a notch, before the
        # frame's association, so a track never takes a newcomer after a gap
        for track in [tr for tr, book in live.items()
                      if (_ends_silence(tr, book, float(t), min_speed, config)
                          if book.confirmed and (book.stopped
                                                 or t - book.last_hit_s > silent_before_s)
                          else not book.confirmed and t - book.born_s > tentative_s)]:
            del live[track]
        pxy, plabels = by_frame.get(frame, no_points)
        xy, counts = _objects(pxy, plabels) if len(pxy) else (np.empty((0, 2)),
                                                              np.empty(0, np.int64))
        ulab = np.unique(plabels)
        at = None if by_label is None else np.searchsorted(dop_label, ulab)
        dop = dop_value[at] if at is not None else np.full(len(ulab), np.nan)
        spread = dop_spread[at] if at is not None else np.full(len(ulab), np.nan)
        sensor = (float(sensor_xy[i_frame, 0]), float(sensor_xy[i_frame, 1]))
        h_rad = None if heading is None else float(heading[i_frame])

        def meta(j):
            """The metadata of object j (Stone Soup's detections carry it)."""
            return {"n_points": int(counts[j]), "doppler_mps": float(dop[j]),
                    "doppler_spread_mps": float(spread[j]), "sensor_xy": sensor,
                    "sensor_heading_rad": h_rad}

        hit_now: dict[object, bool] = {}
        meas_of: dict[object, int] = {}          # track -> the object (index) that updated it
        partial: set = set()                     # JPDA: not detected, yet updated in part
        # Two-stage association: confirmed tracks first, tentative tracks with what is left. A
        # new track's wide velocity prior gives it a small Mahalanobis distance to anything
        # nearby, so one joint assignment lets clutter-born tracks steal a confirmed track's
        # detection (Blackman & Popoli 1999, sec. 6.3: confirmed tracks have priority). With
        # tracker.priority_max_coast_frames a long-silent confirmed track joins the second.
        first = {tr: _first_stage(book, float(t), silent_first_s) for tr, book in live.items()}
        if fast:
            free = np.ones(len(xy), bool)
            F = np.asarray(parts.predictor.transition_model.matrix(time_interval=ts - prev_ts),
                           float) if live else None
            Q = np.asarray(parts.predictor.transition_model.covar(time_interval=ts - prev_ts),
                           float) if live else None
            terms = None
            if parts.doppler_std_mps is not None and len(xy):
                los = xy.T - np.array(sensor)[:, None]
                rng = np.hypot(los[0], los[1])
                terms = (dop, np.maximum(counts.astype(float), 1.0),
                         los / np.where(rng > 0, rng, 1.0), np.isfinite(dop) & (rng > 0))
            for stage in (True, False):
                tracks = [tr for tr in live if first[tr] is stage]
                if not tracks:
                    continue
                q_stage = Q
                held = np.array([live[tr].stopped for tr in tracks], bool)
                if held.any():         # a stopped track does not diffuse over a gap
                    q_stage = np.repeat(Q[None], len(tracks), axis=0)
                    q_stage[held] = _held_noise(parts, ts - prev_ts, period)
                hits, det = _gnn_stage(tracks, xy, free, F, q_stage, R_meas, parts.gate, terms,
                                       parts.doppler_std_mps)
                free[det[hits]] = False
                for track, hit, j in zip(tracks, hits, det):
                    hit_now[track] = bool(hit)
                    if hit:
                        meas_of[track] = int(j)
                if config.doppler_update_std_mps is not None and hits.any():
                    upd = [tr for tr, hit in zip(tracks, hits) if hit]
                    jj = det[hits]
                    xs, ps = _range_rate_update(np.stack([tr.x for tr in upd]),
                                                np.stack([tr.P for tr in upd]), dop[jj],
                                                counts[jj], sensor, config.doppler_update_std_mps)
                    for tr, xi, pi in zip(upd, xs, ps):
                        tr.x, tr.P = xi, pi
        else:
            for track in live:     # a stopped track does not diffuse over a gap
                if live[track].stopped:
                    _held_for(track, ts, prev_ts, period)
            order = [Detection(p.reshape(2, 1), timestamp=ts,
                               measurement_model=parts.measurement_model, metadata=meta(j))
                     for j, p in enumerate(xy)]
            rank = {id(d): i for i, d in enumerate(order)}
            detections = set(order)
            used: set = set()
            for stage in (True, False):
                tracks = {tr for tr in live if first[tr] is stage}
                if not tracks:
                    continue
                assoc = parts.associator.associate(tracks, detections - used, ts)
                for track, hyp in assoc.items():
                    if parts.jpda:
                        state, hit = _jpda_posterior(track, hyp, parts.updater)
                        if not hit and any(bool(h) for h in hyp):
                            partial.add(track)
                        if stage:
                            used.update(h.measurement for h in hyp if h)
                        if hit:
                            best = max((h for h in hyp if h), key=lambda h: h.probability)
                            meas_of[track] = rank[id(best.measurement)]
                            if not stage:
                                used.add(best.measurement)
                    else:
                        hit = bool(hyp)
                        state = parts.updater.update(hyp) if hit else hyp.prediction
                        if hit:
                            used.add(hyp.measurement)
                            meas_of[track] = rank[id(hyp.measurement)]
                    if hit and config.doppler_update_std_mps is not None:
                        j = meas_of[track]
                        xs, ps = _range_rate_update(
                            np.asarray(state.state_vector, float).reshape(1, -1),
                            np.asarray(state.covar, float)[None], dop[j:j + 1],
                            counts[j:j + 1], sensor, config.doppler_update_std_mps)
                        state = type(state)(xs[0].reshape(-1, 1), ps[0], state.hypothesis,
                                            state.timestamp)
                    track.append(state)
                    hit_now[track] = hit
        if min_speed is not None:
            _silence_in_notch(live, hit_now, sensor, min_speed, config, partial)
        # Track management: M-of-N confirmation, deletion of failed tentatives and of confirmed
        # tracks silent for longer than max_misses frame periods (silence in the notch excepted).
        for track, hit in hit_now.items():
            book = live[track]
            book.hits.append(hit)
            if hit:
                book.last_hit_s = float(t)
                j = meas_of[track]
                book.dopplers.append((int(counts[j]), float(dop[j])))
            if not book.confirmed:
                if sum(book.hits[-n:]) >= m or (min_speed is None
                                                 and _doppler_confirms(book, config, n)):
                    book.confirmed = True
                elif sum(book.hits) + max(n - len(book.hits), 0) < m or len(book.hits) >= n:
                    del live[track]
                    continue
            # Stone Soup's UpdateTimeDeleter.check_for_deletion(track) read off the time of
            # the last hit (a walk over the track's states was 9 % of the stage); on regular
            # frames the deletions of UpdateTimeStepsDeleter(max_misses + 1)
            if (book.confirmed and not hit
                    and (book.stopped or t - book.last_hit_s > silent_after_miss_s)
                    and _ends_silence(track, book, float(t), min_speed, config)):
                del live[track]
        if pose is not None:
            coasting = [tr for tr, hit in hit_now.items() if not hit and tr in live]
            if coasting:
                xy_c = np.array([_state_arrays(tr)[0][[0, 2]] for tr in coasting])
                inside = _in_field_of_view(xy_c, pose[i_frame], fov_cos)
                for tr, keep in zip(coasting, inside):
                    if not keep:
                        del live[tr]
        # Births in the objects' order (Stone Soup returns a set), so ids do not depend on hashes.
        if fast:
            born = []
            for j in np.flatnonzero(free):
                x0, p0 = parts.initiator.start(xy[j].reshape(2, 1), meta(j))
                born.append((_Track(np.asarray(x0, float).ravel(), np.asarray(p0, float)),
                             int(j)))
        else:
            born = [(tr, rank[id(tr[0].hypothesis.measurement)])
                    for tr in parts.initiator.initiate(detections - used, ts)]
            born.sort(key=lambda tj: tj[1])
        for track, j in born:
            live[track] = _Book(next_id, [True], born_s=float(t), last_hit_s=float(t),
                                dopplers=[(int(counts[j]), float(dop[j]))])
            next_id += 1
            hit_now[track] = True
            meas_of[track] = j
            if m <= 1:
                live[track].confirmed = True
        prev_ts = ts
        for track, book in live.items():
            sv, c = _state_arrays(track)
            out["frame"].append(frame)
            out["time_s"].append(t)
            out["track_id"].append(book.track_id)
            out["x_m"].append(sv[0])
            out["y_m"].append(sv[2])
            out["vx_mps"].append(sv[1])
            out["vy_mps"].append(sv[3])
            out["cov_xx"].append(c[0, 0])
            out["cov_xy"].append(c[0, 2])
            out["cov_yy"].append(c[2, 2])
            out["cov_vxvx"].append(c[1, 1])
            out["cov_vxvy"].append(c[1, 3])
            out["cov_vyvy"].append(c[3, 3])
            out["cov_xvx"].append(c[0, 1])                 # state order [x, vx, y, vy]
            out["cov_xvy"].append(c[0, 3])
            out["cov_yvx"].append(c[2, 1])
            out["cov_yvy"].append(c[2, 3])
            out["confirmed"].append(book.confirmed)
            out["coasting"].append(not hit_now[track])
            j = meas_of.get(track)
            out["n_points"].append(int(counts[j]) if j is not None else 0)
            out["doppler_mps"].append(float(dop[j]) if j is not None else np.nan)
            out["doppler_spread_mps"].append(float(spread[j]) if j is not None else np.nan)
    return out


def _frame_poses(frames: pd.DataFrame) -> np.ndarray:
    """(F, 4) per row of ``frames``: the sensor's x, y (m) and boresight (-sin h, cos h) from
    :data:`SENSOR_COLUMNS` and :data:`SENSOR_HEADING_COLUMN`."""
    h = np.radians(frames[SENSOR_HEADING_COLUMN].to_numpy(float))
    return np.column_stack([frames[list(SENSOR_COLUMNS)].to_numpy(float), -np.sin(h),
                            np.cos(h)])


def _in_field_of_view(xy: np.ndarray, pose: np.ndarray, cos_half: float) -> np.ndarray:
    """(N,) bool: positions ``xy`` (N, 2; m) within the azimuth field of view of the sensor at
    ``pose`` (x, y, boresight unit vector; :func:`_frame_poses`) whose half width has cosine
    ``cos_half``: the bearing's cosine r.b / |r| is at least it (the sensor's own position
    counts as inside)."""
    r = xy - pose[:2]
    return r @ pose[2:] >= np.hypot(r[:, 0], r[:, 1]) * cos_half


def _track_chunk(chunk: list, config: TrackerConfig,
                 min_speed: float | None = None) -> pd.DataFrame | None:
    """Track the groups of one chunk (a worker's share): [(group, objects, frames)]."""
    parts = _parts(config)
    pieces = []
    for g, objects, fr in chunk:
        res = pd.DataFrame(_track_group(objects, fr, config, parts, min_speed))
        res.insert(0, "group", g)
        pieces.append(res)
    return pd.concat(pieces, ignore_index=True) if pieces else None


def track_points(points: pd.DataFrame, config: TrackerConfig, jobs: int = 1, *,
                 source: str = "", min_detectable_speed_mps: float | None = None
                 ) -> pd.DataFrame:
    """Tracks of the points of many frames: one row per live track per frame.

    Args:
        points: one row per point: ``frame`` (int), ``time_s`` (float, s; strictly increasing
            with ``frame`` within a group), ``x_m``, ``y_m`` (m, any one Cartesian frame of
            reference: the world frame of a driving scene or a recording's sensor frame);
            optional ``group`` (independent runs, e.g. scene ids, tracked separately, track ids
            restart at 0 in each) and ``velocity_mps`` (radial speed; not used by this CV
            position tracker). A row with NaN ``x_m``/``y_m`` marks a frame that was observed
            without any point (tracks coast through it); frames absent from ``points`` are not
            stepped. Optional ``velocity_over_ground_mps`` (ego-motion-compensated radial speed,
            m/s): its per-object median is carried to the track rows (``doppler_mps``) and,
            with ``config.doppler_std_mps``, gates the association; optional ``sensor_x_m``,
            ``sensor_y_m``: the sensor's position at the point's frame (m, same frame of
            reference, one value per frame, a frame's NaN-coordinate row included; the origin
            without them), the Doppler's line of sight; optional ``sensor_heading_deg``: its
            boresight (:data:`SENSOR_HEADING_COLUMN`). With that column and
            ``config.field_of_view_deg``, a track whose row is coasting (no detection updated
            it this frame; JPDA: its detections carry at most half the association
            probability, as the ``coasting`` column) at a bearing outside the field of view is
            deleted (no row from that frame on); without the column nothing is deleted for it
            (recordings differ in which axis the sensor looks along).
        config: the tracker group (:class:`~blindspot.track.config.TrackerConfig`).
        jobs: worker processes over the groups (:func:`blindspot.parallel.parallel_map`; the
            result does not depend on it).
        source: where the points come from (their file), named in every TrackingError.
        min_detectable_speed_mps: the sensor's Doppler notch (m/s): it reports no point whose
            radial speed over ground is below this (static clutter removed on the sensor or
            by the reader). Each frame a confirmed track goes silent it takes that negative
            information (:mod:`blindspot.track.stopped`: its radial speed drawn into the
            notch, its tangential speed kept); a track whose silence outlasts ``max_misses``'
            time is held as stopped where it was last detected, instead of deleted, when what
            was last seen of it was slowing into the notch and standing, for at most
            ``tracker.max_stop_s``. The Doppler early confirmation
            (``tracker.doppler_confirm_log_ratio``) is off: every reported point moves by
            selection. Needs ``tracker.moving`` (its ``doppler_std_mps``). None (points of the
            static world included, as the driving chain gives them): no notch.

    Returns:
        DataFrame with (``group``), ``frame``, ``time_s``, ``track_id`` (int, unique within a
        group, never reused), ``x_m``, ``y_m``, ``vx_mps``, ``vy_mps`` (filtered state, m and
        m/s), ``cov_xx``, ``cov_xy``, ``cov_yy`` (position covariance, m^2), ``cov_vxvx``,
        ``cov_vxvy``, ``cov_vyvy`` (velocity covariance, m^2/s^2), ``confirmed`` (M-of-N
        passed), ``coasting`` (predicted without a measurement this frame), ``n_points`` (points
        of the object that updated the track this frame, 0 when coasting), ``doppler_mps`` (the
        median ``velocity_over_ground_mps`` of those points, m/s; NaN when coasting or when the
        points lack that column: the evidence of :func:`blindspot.track.moving.moving_tracks`),
        ``doppler_spread_mps`` (their sample standard deviation, ddof 1, m/s, over the points
        with a finite radial speed, while ``n_points`` counts them all: the object's Doppler
        spread; NaN as ``doppler_mps`` and for a one-point object), ``cov_xvx``, ``cov_xvy``,
        ``cov_yvx``, ``cov_yvy`` (position-velocity cross-covariance, m^2/s: the whole
        filtered state, which :class:`blindspot.safety.predict.TrackState` forecasts). Tentative
        tracks are included (``confirmed`` False): filter on ``confirmed`` for reported tracks.

    Raises:
        TrackingError: a missing column, a null frame id or time, a non-integer frame, a
            non-numeric coordinate, an infinite time or one beyond :data:`MAX_TIME_S` (not
            seconds: epoch milliseconds or nanoseconds), or a time that does not increase
            with the frame within a group; a ``config`` that is not a TrackerConfig or
            ``jobs`` not an integer >= 1; a sensor
            pose column (``sensor_x_m``, ``sensor_y_m``, ``sensor_heading_deg``) without the
            position's other column, non-numeric, non-finite on a frame or taking two values
            within one frame.
    """
    has_group = _check_points(points, source)
    who = _who(source)
    _check_config(config, who)
    check_count(jobs, "jobs", ge=1, error=TrackingError, who=who)
    notch = min_detectable_speed_mps
    if notch is not None:
        notch = check_number(notch, "min_detectable_speed_mps", gt=0.0, unit="m/s (or None)",
                             error=TrackingError, who=who)
    if notch is not None and config.moving is None:
        raise TrackingError(f"{who}: min_detectable_speed_mps needs tracker.moving (its "
                            "doppler_std_mps: a point's radial-speed spread, which tells a track "
                            "slowing into the notch); found tracker.moving null")
    keys = (["group"] if has_group else []) + ["frame"]
    # the sensor's pose per frame (the field of view needs to know where it looks: only with the
    # heading column)
    pose_cols = [c for c in (*SENSOR_COLUMNS, SENSOR_HEADING_COLUMN) if c in points.columns]
    frames = (points[keys + ["time_s"] + pose_cols].drop_duplicates(keys).sort_values(keys)
              .reset_index(drop=True))
    if pose_cols:
        every = config.field_of_view_deg is not None and SENSOR_HEADING_COLUMN in pose_cols
        _check_poses(points, keys, frames, pose_cols, every_frame=every)
    gkey = frames["group"] if has_group else pd.Series(0, index=frames.index)
    dtime = frames["time_s"].diff().to_numpy()
    first = (gkey != gkey.shift()).to_numpy()
    if (dtime[~first] <= 0).any():
        bad = frames.loc[np.flatnonzero((dtime <= 0) & ~first)[0]]
        raise TrackingError(f"{who}: time_s must increase with frame within a group; "
                            f"found time_s = {bad['time_s']} at frame {bad['frame']}, not after "
                            f"the previous frame's")
    labelled = _labelled(points, keys, config)
    if has_group:
        obj_groups = dict(list(labelled.groupby("group", sort=False)))
        items = [(g, obj_groups.get(g, labelled.iloc[:0]), fr)
                 for g, fr in frames.groupby("group", sort=True)]
        # groups are independent: contiguous chunks over the worker processes, order kept
        n_chunks = min(len(items), 4 * jobs) if jobs > 1 else 1
        bounds = np.linspace(0, len(items), n_chunks + 1).round().astype(int)
        chunks = [items[a:b] for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
        pieces = [p for p in parallel_map(partial(_track_chunk, config=config, min_speed=notch),
                                             chunks, jobs)
                  if p is not None]
        result = pd.concat(pieces, ignore_index=True) if pieces else None
    else:
        result = pd.DataFrame(_track_group(labelled, frames, config, _parts(config), notch))
    cols = (["group"] if has_group else []) + list(OUTPUT_COLUMNS)
    if result is None or result.empty:
        empty = {c: pd.Series(dtype=float) for c in cols}
        for c in ("frame", "track_id", "n_points"):
            empty[c] = pd.Series(dtype="int64")
        for c in ("confirmed", "coasting"):
            empty[c] = pd.Series(dtype=bool)
        if has_group:
            empty["group"] = pd.Series(dtype=points["group"].dtype)
        return pd.DataFrame(empty)[cols]
    return result.astype({"frame": "int64", "track_id": "int64", "confirmed": bool,
                          "coasting": bool, "n_points": "int64"})[cols]
