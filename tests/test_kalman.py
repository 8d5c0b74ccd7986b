"""blindspot.kalman's one-step functions on stacks of states: the same bytes as one by one
(the tracker's vectorised GNN step corrects every matched track in one call)."""

from __future__ import annotations

import numpy as np

from blindspot import kalman


def _random_states(rng, n: int):
    F, Q, H, R = kalman.cv_model(0.05, 0.5, 0.15)
    a = rng.normal(size=(n, 4, 4))
    P = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(4)
    x = rng.normal(size=(n, 4, 1)) * 10
    return x, P, F, Q, H, R


def test_stacked_predict_and_update_equal_one_at_a_time():
    rng = np.random.default_rng(7)
    x, P, F, Q, H, R = _random_states(rng, 64)
    z = rng.normal(size=(64, 2, 1)) * 10
    Pp = kalman.predict_covariance(P, F, Q)
    xp = F @ x
    zhat, S, PHt = H @ xp, H @ Pp @ H.T + R, Pp @ H.T
    xs, Ps = kalman.update(xp, Pp, z, zhat, S, PHt)
    for i in range(len(x)):
        xi, Pi = kalman.predict(x[i], P[i], F, Q)
        assert np.array_equal(xi, xp[i]) and np.array_equal(Pi, Pp[i])
        mi = kalman.measurement_moments(xi, Pi, H, R)
        xu, Pu = kalman.update(xi, Pi, z[i], *mi)
        assert np.array_equal(xu, xs[i]) and np.array_equal(Pu, Ps[i])
        assert np.array_equal(Pu, Pu.T)
