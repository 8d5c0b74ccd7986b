"""Line-of-sight occlusion by the car footprint, against a loop-based reference and the geometry."""

import numpy as np
import pytest

from blindspot.radar.occlusion import GeometryError, point_in_polygon, segment_crosses_polygon

# The paper scene's car footprint: x 1.5..3.3, y 4.8..9.3 (conf/scene/paper.yaml).
CAR = np.array([[1.5, 4.8], [3.3, 4.8], [3.3, 9.3], [1.5, 9.3]])


def _reference_crosses(p, poly):
    """Segment (0,0)->p against each edge by solving the 2x2 system of the two lines."""
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        m = np.array([[p[0], a[0] - b[0]], [p[1], a[1] - b[1]]])
        if abs(np.linalg.det(m)) < 1e-12:
            continue
        s, t = np.linalg.solve(m, a)  # s along 0->p, t along a->b
        if 0 < s < 1 and 0 < t < 1:
            return True
    return False


def _reference_inside(p, poly):
    """Inside a convex polygon: on the same side of every edge."""
    sides = [(b - a)[0] * (p - a)[1] - (b - a)[1] * (p - a)[0] for a, b in zip(poly, np.roll(poly, -1, axis=0))]
    return all(s > 0 for s in sides) or all(s < 0 for s in sides)


def test_behind_the_car_is_occluded_beside_and_in_front_are_not():
    pts = np.array([
        [2.4, 12.0],   # straight behind the car's centre
        [3.4, 20.0],   # far behind, just inside the shadow's left edge (9.65 vs 9.16 deg)
        [6.0, 10.2],   # behind, on the pedestrian's line
        [5.0, 7.0],    # beside the car (azimuth 35.5 deg, outside the shadow)
        [2.4, 3.0],    # in front of the car
        [-1.0, 10.0],  # left of the car
        [0.5, 15.0],   # far, left of the shadow (1.9 deg)
    ])
    got = segment_crosses_polygon(pts, CAR)
    np.testing.assert_array_equal(got, [True, True, True, False, False, False, False])


def test_a_point_on_the_visible_face_does_not_occlude_itself():
    on_face = np.array([[1.5, 6.0], [2.0, 4.8], [1.5, 4.8]])  # left side, near end, near corner
    assert not segment_crosses_polygon(on_face, CAR).any()
    far_face = np.array([[3.3, 7.0], [2.4, 9.3]])             # right side and far end: hidden
    assert segment_crosses_polygon(far_face, CAR).all()


def test_vectorised_matches_loop_reference_on_random_points_and_polygons():
    rng = np.random.default_rng(7)
    for _ in range(5):
        # a random convex quadrilateral (a rotated, shifted rectangle)
        ang = rng.uniform(0, np.pi)
        rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        half = rng.uniform(0.5, 3.0, size=2)
        rect = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
        poly = rect @ rot.T + rng.uniform([-5, 3], [5, 12])
        pts = rng.uniform([-10, -2], [10, 20], size=(20, 25, 2))   # (F, K, 2)
        got = segment_crosses_polygon(pts, poly)
        assert got.shape == (20, 25)
        ref = np.array([_reference_crosses(p, poly) for p in pts.reshape(-1, 2)]).reshape(20, 25)
        np.testing.assert_array_equal(got, ref)
        inside = point_in_polygon(pts, poly)
        ref_in = np.array([_reference_inside(p, poly) for p in pts.reshape(-1, 2)]).reshape(20, 25)
        np.testing.assert_array_equal(inside, ref_in)
        # every point inside the footprint is hidden from the radar (outside it)
        assert got[inside].all()


def test_origin_moves_the_radar():
    # from (10, 0) the car hides different points than from the origin
    p = np.array([[2.4, 12.0], [-4.0, 10.0]])
    np.testing.assert_array_equal(segment_crosses_polygon(p, CAR, origin=[10.0, 0.0]), [False, True])


def test_bad_shapes_raise():
    with pytest.raises(GeometryError, match=r"points must be points \(\.\.\., 2\).*shape \(3, 3\)"):
        segment_crosses_polygon(np.zeros((3, 3)), CAR)
    with pytest.raises(GeometryError, match=r"polygon must be vertices \(E >= 3, 2\)"):
        segment_crosses_polygon(np.zeros((3, 2)), CAR[:2])
