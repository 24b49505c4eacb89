"""Correct implementations of Chapter 7's camera model, written differently from cvkit's reference.

They play the part of good students: a check must accept every one of them. Most work point by
point in plain Python loops (the way a first version looks); others use another formulation
(Rodrigues' formula for the elementary rotations, a Gram–Schmidt RQ decomposition, np.block,
multiplication by 1/w). None calls cvkit or a library that the guard forbids.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg


# --------------------------------------------------------------------------------------------
# homogeneous coordinates
# --------------------------------------------------------------------------------------------
def to_homogeneous(points):
    """np.pad with a constant 1."""
    pts = np.asarray(points, dtype=np.float64)
    widths = [(0, 0)] * (pts.ndim - 1) + [(0, 1)]
    return np.pad(pts, widths, constant_values=1.0)


def from_homogeneous(points_h):
    """Multiply by 1/w (1/0 = inf; 0·inf = nan, as 0/0)."""
    pts = np.asarray(points_h, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / pts[..., -1:]
        return pts[..., :-1] * inverse


# --------------------------------------------------------------------------------------------
# matrices
# --------------------------------------------------------------------------------------------
def intrinsic_matrix(fu, fv, u0, v0, skew=0.0):
    A = np.zeros((3, 3))
    A[0, 0], A[0, 1], A[0, 2] = fu, skew, u0
    A[1, 1], A[1, 2] = fv, v0
    A[2, 2] = 1
    return A


def _axis_rotation(axis, angle):
    """Rodrigues: R = I + sin a·K + (1 − cos a)·K² with K the cross-product matrix of the axis."""
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


def rotation_matrix(roll, pitch, yaw):
    """Turn the vector by roll about x, then pitch about y, then yaw about z."""
    R = np.eye(3)
    for axis, angle in (((1, 0, 0), roll), ((0, 1, 0), pitch), ((0, 0, 1), yaw)):
        R = _axis_rotation(axis, float(angle)) @ R
    return R


def extrinsic_matrix(R, t):
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3, 1)
    return np.block([[R, t], [np.zeros((1, 3)), np.ones((1, 1))]])


def projection_matrix(A, R, t):
    """[A·R | A·t]."""
    A = np.asarray(A, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    P = np.empty((3, 4))
    P[:, :3] = A @ R
    P[:, 3] = A @ t
    return P


def project(P, points_world):
    """One point at a time."""
    P = np.asarray(P, dtype=np.float64)
    pts = np.asarray(points_world, dtype=np.float64)
    out = np.empty((len(pts), 2))
    for i, point in enumerate(pts):
        homogeneous = np.append(point, 1.0) if point.size == 3 else point
        a, b, c = P @ homogeneous
        with np.errstate(divide="ignore", invalid="ignore"):
            out[i] = np.float64(a) / np.float64(c), np.float64(b) / np.float64(c)
    return out


def decompose_projection(P):
    """Row by row (Gram–Schmidt from the bottom): M = λ·A·R with A upper triangular gives
    m3 = λ·r3, m2 = λ(fv·r2 + v0·r3), m1 = λ(fu·r1 + s·r2 + u0·r3)."""
    P = np.asarray(P, dtype=np.float64)
    M, p4 = P[:, :3], P[:, 3]
    if np.linalg.matrix_rank(M) < 3:
        raise ValueError("P's left 3x3 block is singular")
    if np.linalg.det(M) < 0:
        M, p4 = -M, -p4
    lam = np.linalg.norm(M[2])
    m1, m2, m3 = M / lam
    r3 = m3
    v0 = m2 @ r3
    rest = m2 - v0 * r3
    fv = np.linalg.norm(rest)
    r2 = rest / fv
    u0 = m1 @ r3
    skew = m1 @ r2
    rest = m1 - skew * r2 - u0 * r3
    fu = np.linalg.norm(rest)
    r1 = rest / fu
    A = np.array([[fu, skew, u0], [0.0, fv, v0], [0.0, 0.0, 1.0]])
    R = np.array([r1, r2, r3])
    t = np.linalg.solve(lam * A, p4)
    return A, R, t


def decompose_projection_scipy(P):
    """scipy.linalg.rq with both sign fixes."""
    P = np.asarray(P, dtype=np.float64)
    sign = np.sign(np.linalg.det(P[:, :3]))
    K, Q = scipy.linalg.rq(sign * P[:, :3])
    D = np.diag(np.sign(np.diag(K)))
    K, Q = K @ D, D @ Q
    t = np.linalg.solve(K, sign * P[:, 3])
    return K / K[2, 2], Q, t


# --------------------------------------------------------------------------------------------
# distortion
# --------------------------------------------------------------------------------------------
def _coefficients(k, p):
    k = list(np.atleast_1d(np.asarray(k, dtype=np.float64))) + [0.0, 0.0]
    p1, p2 = (float(v) for v in p)
    return float(k[0]), float(k[1]), float(k[2]), p1, p2


def distort(xy_normalized, k=(0.0, 0.0, 0.0), p=(0.0, 0.0)):
    """Point by point, with the powers of r written out."""
    k1, k2, k3, p1, p2 = _coefficients(k, p)
    out = []
    for x, y in np.asarray(xy_normalized, dtype=np.float64):
        r = math.hypot(x, y)
        radial = 1 + k1 * r ** 2 + k2 * r ** 4 + k3 * r ** 6
        out.append([x * radial + 2 * p1 * x * y + p2 * (r ** 2 + 2 * x ** 2),
                    y * radial + p1 * (r ** 2 + 2 * y ** 2) + 2 * p2 * x * y])
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def undistort_points(xy_distorted, k, p, iterations=20):
    """Point by point fixed-point iteration."""
    k1, k2, k3, p1, p2 = _coefficients(k, p)
    out = []
    for xd, yd in np.asarray(xy_distorted, dtype=np.float64):
        x, y = xd, yd
        for _ in range(iterations):
            r2 = x * x + y * y
            radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
            dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
            x, y = (xd - dx) / radial, (yd - dy) / radial
        out.append([x, y])
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def project_full(points_world, A, R, t, k=(0.0, 0.0, 0.0), p=(0.0, 0.0)):
    """Through the 4×4 extrinsic matrix and homogeneous pixels, point by point."""
    A = np.asarray(A, dtype=np.float64)
    G = extrinsic_matrix(R, t)
    out = []
    for point in np.asarray(points_world, dtype=np.float64):
        xc, yc, zc, _ = G @ np.append(point, 1.0)
        xd, yd = distort([[xc / zc, yc / zc]], k, p)[0]
        u, v, w = A @ np.array([xd, yd, 1.0])
        out.append([u / w, v / w])
    return np.array(out, dtype=np.float64).reshape(-1, 2)


ALTERNATIVES = {
    "camera.to_homogeneous": to_homogeneous,
    "camera.from_homogeneous": from_homogeneous,
    "camera.intrinsic_matrix": intrinsic_matrix,
    "camera.rotation_matrix": rotation_matrix,
    "camera.extrinsic_matrix": extrinsic_matrix,
    "camera.projection_matrix": projection_matrix,
    "camera.project": project,
    "camera.decompose_projection": decompose_projection,
    "camera.distort": distort,
    "camera.undistort_points": undistort_points,
    "camera.project_full": project_full,
}

EXTRA_ALTERNATIVES = [
    ("camera.decompose_projection", decompose_projection_scipy),
]
