"""Line-of-sight occlusion by a polygon footprint, in the ground plane.

A return from a point is blocked when the straight segment from the radar (the origin) to the
point crosses an edge of an occluding footprint (the parked car). Everything is vectorised over
points and polygon edges: an (..., 2) array of points against an (E, 2) polygon gives an (...)
boolean array, with no Python loop.

The test is the classic orientation test for two segments, specialised to segments that start at
the origin: segment 0->p and edge q0->q1 cross properly when q0 and q1 lie strictly on opposite
sides of the line through 0 and p, and 0 and p lie strictly on opposite sides of the line through
q0 and q1. Touching (a point exactly on an edge, or a segment through a vertex) does not count,
so a scatterer painted on the visible face of the car does not occlude itself.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import checked_array


class GeometryError(ValueError):
    """Points, a polygon or an origin of the wrong shape or kind, or not finite."""


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z-component of the 2-D cross product, broadcast over leading axes."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def polygon_edges(polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(E, 2) vertices (closed implicitly) -> (start (E, 2), end (E, 2)) of each edge.
    Raises GeometryError unless ``polygon`` is (E >= 3, 2) finite real coordinates."""
    poly = checked_array(polygon, "polygon", GeometryError, kind="real", ndim=2,
                         lengths={1: 2}, min_lengths={0: 3}, axes="vertices (E >= 3, 2) in m")
    poly = poly.astype(float, copy=False)
    return poly, np.roll(poly, -1, axis=0)


def _points(points: np.ndarray) -> np.ndarray:
    p = checked_array(points, "points", GeometryError, kind="real", min_ndim=1,
                      lengths={-1: 2}, axes="points (..., 2) of (x, y) in m")
    return p.astype(float, copy=False)


def segment_crosses_polygon(points: np.ndarray, polygon: np.ndarray,
                            origin: np.ndarray | None = None) -> np.ndarray:
    """Whether the segment origin->point crosses the polygon's boundary.

    points : (..., 2) end points (x, y), m.
    polygon : (E, 2) vertices of the occluding footprint, in order (either orientation).
    origin : (2,) start of every segment (the radar), default (0, 0).
    Returns bool (...): True where the line of sight is blocked.
    Raises GeometryError for points, polygon or origin of another shape, kind, or not finite.
    """
    p = _points(points)
    q0, q1 = polygon_edges(polygon)
    if origin is not None:
        o = checked_array(origin, "origin", GeometryError, kind="real", ndim=1, lengths={0: 2},
                          axes="a point (2,) in m").astype(float)
        p, q0, q1 = p - o, q0 - o, q1 - o
    pe = p[..., None, :]                      # (..., 1, 2) against (E, 2) edges
    # sides of the edge end points relative to the line 0 -> p
    s0 = _cross(pe, q0)
    s1 = _cross(pe, q1)
    # sides of 0 and p relative to the edge line q0 -> q1
    d = q1 - q0
    t0 = _cross(d, -q0)                       # (E,)
    t1 = _cross(d, pe - q0)                   # (..., E)
    crosses = (s0 * s1 < 0) & (t0 * t1 < 0)
    return crosses.any(axis=-1)


def segment_crosses_polygons(points: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """:func:`segment_crosses_polygon` for N scenes at once, each with its own footprint.

    points : (N, ..., 2) end points (x, y), m, of scene n in ``points[n]``.
    polygons : (N, E, 2) vertices of each scene's occluding footprint, in order.
    Returns bool (N, ...): True where the line of sight from the radar (origin) is blocked.
    Raises GeometryError for arrays of another shape or kind, N that differ, or non-finite values.
    """
    p = _points(points)
    poly = checked_array(polygons, "polygons", GeometryError, kind="real", ndim=3,
                         lengths={2: 2}, min_lengths={1: 3}, axes="vertices (N, E >= 3, 2) in m")
    if p.ndim < 2 or p.shape[0] != poly.shape[0]:
        raise GeometryError(f"segment_crosses_polygons: points {p.shape} must be (N, ..., 2) "
                            f"with N = {poly.shape[0]} polygons")
    n, e = poly.shape[:2]
    flat = p.reshape(n, -1, 1, 2)                                        # (N, M, 1, 2)
    q0 = poly.astype(float)[:, None, :, :]                               # (N, 1, E, 2)
    q1 = np.roll(q0, -1, axis=2)
    s0, s1 = _cross(flat, q0), _cross(flat, q1)                          # (N, M, E)
    d = q1 - q0
    t0, t1 = _cross(d, -q0), _cross(d, flat - q0)
    crosses = (s0 * s1 < 0) & (t0 * t1 < 0)
    return crosses.any(axis=-1).reshape(p.shape[:-1])


def point_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule inside test: (..., 2) points, (E, 2) polygon -> bool (...).
    Raises GeometryError as :func:`segment_crosses_polygon`."""
    p = _points(points)[..., None, :]
    q0, q1 = polygon_edges(polygon)
    straddles = (q0[:, 1] > p[..., 1]) != (q1[:, 1] > p[..., 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = q0[:, 0] + (p[..., 1] - q0[:, 1]) * (q1[:, 0] - q0[:, 0]) / (q1[:, 1] - q0[:, 1])
    hits = straddles & (p[..., 0] < x_at)
    return (hits.sum(axis=-1) % 2) == 1


def segments_blocked(points: np.ndarray, origins: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """Whether the segment origin->point crosses any of several polygons, for a moving origin.

    points : (..., 2) end points (x, y), m.
    origins : (..., 2) start of each segment (a moving radar: one origin per time), broadcast
        against ``points``.
    polygons : (C, E, 2) footprints of C occluders (C may be 0: nothing is blocked).
    Returns bool (broadcast shape of points and origins without the last axis). The same
    orientation test as :func:`segment_crosses_polygon` (touching does not count), vectorised
    over points, origins, occluders and edges.
    Raises GeometryError for arrays of another shape or kind, or not finite.
    """
    p = _points(points)
    o = checked_array(origins, "origins", GeometryError, kind="real", min_ndim=1,
                      lengths={-1: 2}, axes="origins (..., 2) of (x, y) in m").astype(float)
    polys = checked_array(polygons, "polygons", GeometryError, kind="real", ndim=3,
                          lengths={2: 2}, axes="polygons (C, E, 2) in m").astype(float)
    shape = np.broadcast_shapes(p.shape, o.shape)[:-1]
    if polys.shape[0] == 0:
        return np.zeros(shape, dtype=bool)
    q0, q1 = polys, np.roll(polys, -1, axis=1)                      # (C, E, 2)
    d = (np.broadcast_to(p, shape + (2,)) - np.broadcast_to(o, shape + (2,)))[..., None, None, :]
    oo = np.broadcast_to(o, shape + (2,))[..., None, None, :]
    a0, a1 = q0 - oo, q1 - oo                                       # edges relative to origin
    s0, s1 = _cross(d, a0), _cross(d, a1)
    e = q1 - q0
    t0 = _cross(e, -a0)
    t1 = _cross(e, d - a0)
    return ((s0 * s1 < 0) & (t0 * t1 < 0)).any(axis=(-1, -2))
