"""Every public function of traj/ that takes arrays refuses NaN/inf, wrong dtypes and wrong
shapes with its module's own error class, naming the argument, what it expected and what it
found (issue 9, item 3). One table of (function, argument) cases x one list of bad variants."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from blindspot.kalman import KalmanError, kalman_filter
from blindspot.traj.baselines import ConstantVelocity, KalmanCV, last_valid_index
from blindspot.arrays import check_array
from blindspot.traj.config import PathSpec
from blindspot.traj.ethucy import (
    EthUcyDataError,
    infer_frame_step,
    random_rotations,
    scene_tracks,
)
from blindspot.traj.evaluation import (
    EvaluationError,
    errors_at_horizons,
    gap_mask,
    score_interpolation,
    score_prediction,
)
from blindspot.traj.forecast import ForecastError, forecast_track
from blindspot.traj.interpolation import InterpolationError, find_gaps, interpolate, pad_history
from blindspot.traj.metrics import MetricShapeError, ade, displacement, fde, path_error, per_step_error
from blindspot.traj.paths import (
    PathDataError,
    in_field_of_view,
    integrate_constant_turn,
    radar_like_noise,
)
from blindspot.traj.predictor import HistoryError, from_frame, heading_frame, heading_frame_pairs
from blindspot.traj.predictor import to_frame
from blindspot.traj.train import rmse_euclidean
from blindspot.traj.windows import WindowError, WindowSet, interpolate_gaps, make_windows

RNG = np.random.default_rng(0)
TRACK = np.cumsum(RNG.normal(size=(12, 2)), axis=0)            # (T, 2)
BATCH = np.stack([TRACK, TRACK + 1.0])                          # (B, T, 2)
KF = KalmanCV().matrices()
ROT = np.broadcast_to(np.eye(2), (2, 2, 2))
OBS = np.array([True, True, False, False, True, True, False, True])

def _lstm():
    """A small untrained LSTM predictor (window 4): only its input checks are exercised."""
    from blindspot.traj.config import LSTMConfig
    from blindspot.traj.lstm import LSTMPredictor, LSTMRegressor, NormStats

    cfg = LSTMConfig(window=4, hidden_size=4, head_hidden=0)
    return LSTMPredictor(LSTMRegressor(cfg), NormStats.fit(BATCH[:, :4], BATCH[:, 4], cfg))


# (id, call with the argument x, good x, argument name, error class, NaN means "missing" here)
FLOAT_CASES = [
    ("ade.pred", lambda x: ade(x, BATCH), BATCH, "pred", MetricShapeError, True),
    ("ade.truth", lambda x: ade(BATCH, x), BATCH, "truth", MetricShapeError, True),
    ("fde.pred", lambda x: fde(x, BATCH), BATCH, "pred", MetricShapeError, True),
    ("displacement.truth", lambda x: displacement(BATCH, x), BATCH, "truth", MetricShapeError,
     True),
    ("per_step_error.pred", lambda x: per_step_error(x, BATCH), BATCH, "pred", MetricShapeError,
     True),
    ("path_error.actual", lambda x: path_error(TRACK, x), TRACK, "actual", MetricShapeError, True),
    ("rmse_euclidean.truth", lambda x: rmse_euclidean(TRACK, x), TRACK, "truth",
     MetricShapeError, True),
    ("lstm.predict", lambda x: _lstm().predict(x, 2), BATCH, "history", HistoryError, True),
    ("lstm.predict_next", lambda x: _lstm().predict_next(x), BATCH[:, -4:], "windows",
     HistoryError, False),
    ("cvm.predict", lambda x: ConstantVelocity().predict(x, 3), BATCH, "history", HistoryError,
     True),
    ("kalman.predict", lambda x: KalmanCV().predict(x, 3), BATCH, "history", HistoryError, True),
    ("kalman.smooth", lambda x: KalmanCV().smooth(x), TRACK, "track", HistoryError, True),
    ("kalman_filter.obs", lambda x: kalman_filter(x, *KF, np.zeros(4), np.eye(4)), BATCH, "obs",
     KalmanError, True),
    ("kalman_filter.F", lambda x: kalman_filter(BATCH, x, *KF[1:], np.zeros(4), np.eye(4)),
     KF[0], "F", KalmanError, False),
    ("heading_frame", lambda x: heading_frame(x), BATCH, "windows", HistoryError, True),
    ("heading_frame_pairs", lambda x: heading_frame_pairs(x), BATCH, "sequences", HistoryError,
     False),
    ("to_frame.points", lambda x: to_frame(x, BATCH[:, 0], ROT), BATCH, "points", HistoryError,
     True),
    ("from_frame.rot", lambda x: from_frame(BATCH, BATCH[:, 0], x), ROT, "rot", HistoryError,
     False),
    ("interpolate", lambda x: interpolate(x, "kalman", smoother=KalmanCV().smooth), TRACK,
     "track", InterpolationError, True),
    ("pad_history", lambda x: pad_history(x, 20), TRACK, "history", InterpolationError, True),
    ("forecast_track", lambda x: forecast_track(x, 6, ConstantVelocity()), TRACK, "track",
     ForecastError, True),
    ("make_windows", lambda x: make_windows(x, 3), BATCH, "paths", WindowError, True),
    ("interpolate_gaps", lambda x: interpolate_gaps(x), BATCH, "paths", WindowError, True),
    ("WindowSet.x", lambda x: WindowSet(x, np.zeros((2, 2)), np.arange(2)), BATCH,
     "WindowSet.x", WindowError, False),
    ("score_prediction.pred", lambda x: score_prediction(x, TRACK, None, 0.1), TRACK, "pred",
     EvaluationError, True),
    ("score_prediction.radar_track", lambda x: score_prediction(TRACK, TRACK, x, 0.1), TRACK,
     "radar_track", EvaluationError, True),
    ("score_interpolation.filled", lambda x: score_interpolation(x, TRACK[:8], OBS, ~OBS),
     TRACK[:8], "filled", EvaluationError, True),
    ("errors_at_horizons", lambda x: errors_at_horizons(x, 0.1, (0.5,)), TRACK[:, 0],
     "err_per_step", EvaluationError, True),
    ("random_rotations", lambda x: random_rotations(x, 2, np.random.default_rng(0)), BATCH,
     "xy", EthUcyDataError, False),
    ("scene_tracks", lambda x: scene_tracks(x), np.array(
        [[0, 1, 0.0, 0.0], [10, 1, 1.0, 0.0], [10, 2, 2.0, 1.0]]), "rows", EthUcyDataError,
     False),
    ("infer_frame_step", lambda x: infer_frame_step(x), np.array(
        [[0, 1, 0.0, 0.0], [10, 1, 1.0, 0.0]]), "rows", EthUcyDataError, False),
    ("radar_like_noise", lambda x: radar_like_noise(x), BATCH, "paths", PathDataError, False),
    ("in_field_of_view", lambda x: in_field_of_view(x, PathSpec()), BATCH, "xy", PathDataError,
     False),
    ("integrate_constant_turn", lambda x: integrate_constant_turn(
        x, np.ones(2), np.zeros(2), np.zeros(2), 5, 0.1), BATCH[:, 0], "start_xy",
     PathDataError, False),
]

BOOL_CASES = [
    ("find_gaps", lambda x: find_gaps(x), OBS, "observed", InterpolationError),
    ("gap_mask", lambda x: gap_mask(x), OBS, "observed", EvaluationError),
    ("last_valid_index", lambda x: last_valid_index(x), OBS[None], "valid", HistoryError),
    ("score_interpolation.hidden", lambda x: score_interpolation(TRACK[:8], TRACK[:8], OBS, x),
     ~OBS, "hidden", EvaluationError),
]


def _with(good, value):
    bad = good.astype(float).copy()
    bad.flat[bad.size // 2] = value
    return bad


FLOAT_VARIANTS = {
    "inf": lambda g: _with(g, np.inf),
    "complex": lambda g: g.astype(complex),
    "object": lambda g: g.astype(object),
    "strings": lambda g: g.astype(str),
    "bools": lambda g: g.astype(bool),
    "extra axis": lambda g: g[..., None],
    "last axis": lambda g: np.concatenate([g, g[..., :1]], axis=-1),
    "scalar": lambda g: np.float64(1.0),
    "ragged": lambda g: [[1.0, 2.0], [3.0]],
}
BOOL_VARIANTS = {
    "floats": lambda g: g.astype(float),
    "strings": lambda g: g.astype(str),
    "object": lambda g: g.astype(object),
    "extra axis": lambda g: g[..., None],
}


def _assert_refused(call, bad, name, error):
    with pytest.raises(error) as err:
        call(bad)
    assert type(err.value) is error or issubclass(type(err.value), error)
    msg = str(err.value)
    assert name in msg and "expected" in msg and "found" in msg, msg


@pytest.mark.parametrize("variant", list(FLOAT_VARIANTS))
@pytest.mark.parametrize(("case", "call", "good", "name", "error", "nan_ok"), FLOAT_CASES,
                         ids=[c[0] for c in FLOAT_CASES])
def test_real_array_arguments_are_checked(case, call, good, name, error, nan_ok, variant):
    call(good)                                   # the good value passes
    if variant == "last axis" and good.ndim == 1:
        pytest.skip("a 1-D argument of any length is valid")
    _assert_refused(call, FLOAT_VARIANTS[variant](good), name, error)


@pytest.mark.parametrize(("case", "call", "good", "name", "error", "nan_ok"), FLOAT_CASES,
                         ids=[c[0] for c in FLOAT_CASES])
def test_nan_is_refused_where_it_means_nothing(case, call, good, name, error, nan_ok):
    bad = _with(good, np.nan)
    if nan_ok:
        call(bad)                                # a missing point: handled, not an error
    else:
        _assert_refused(call, bad, name, error)


@pytest.mark.parametrize("variant", list(BOOL_VARIANTS))
@pytest.mark.parametrize(("case", "call", "good", "name", "error"), BOOL_CASES,
                         ids=[c[0] for c in BOOL_CASES])
def test_boolean_mask_arguments_are_checked(case, call, good, name, error, variant):
    call(good)
    _assert_refused(call, BOOL_VARIANTS[variant](good), name, error)


def test_integer_arguments_are_checked():
    with pytest.raises(HistoryError, match="horizon: expected an integer >= 1, found 2.5"):
        ConstantVelocity().predict(BATCH, 2.5)
    with pytest.raises(HistoryError, match="horizon: expected an integer >= 1, found True"):
        KalmanCV().predict(BATCH, True)
    with pytest.raises(WindowError, match="stride: expected an integer >= 1, found '2'"):
        make_windows(BATCH, 3, "2")
    with pytest.raises(WindowError, match="WindowSet.path_id: expected integers, found 0.5"):
        WindowSet(BATCH, np.zeros((2, 2)), np.array([0.5, 1.0]))
    with pytest.raises(ForecastError, match="start: expected an integer >= 1"):
        forecast_track(TRACK, 2.0, ConstantVelocity())
    with pytest.raises(EthUcyDataError, match="copies: expected an integer >= 0"):
        random_rotations(BATCH, -1, np.random.default_rng(0))


DTYPES = st.sampled_from(["f8", "f4", "i8", "u1", "c16", "?", "U3", "O"])


@given(dtype=DTYPES, shape=st.lists(st.integers(0, 3), min_size=0, max_size=4),
       fill=st.sampled_from([0.0, 1.5, np.nan, np.inf, -np.inf]))
def test_check_array_returns_the_checked_array_or_raises_the_given_error(dtype, shape, fill):
    """Whatever comes in, check_array returns a finite float64 array of the pattern's shape or
    raises the error class it was given (never a numpy TypeError)."""
    class Mine(ValueError):
        pass

    if np.dtype(dtype).kind in "iu?" and not np.isfinite(fill):
        fill = 1.0                                   # nan/inf have no integer or bool form
    value = np.full(shape, fill).astype(dtype)
    try:
        out = check_array(value, "arg", ("...", "T", 2), error=Mine, who="f")
    except Mine as err:
        assert "f: arg: expected" in str(err)
        return
    assert out.dtype == np.float64 and out.ndim >= 2 and out.shape[-1] == 2
    assert np.isfinite(out).all() and np.dtype(dtype).kind in "iuf"
