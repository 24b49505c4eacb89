"""Chapter 7 camera model (cvkit.camera) against OpenCV / SciPy oracles and its own definitions.

Parameter mappings (cvkit -> oracle):
- distortion ``k = (k1, k2, k3), p = (p1, p2)`` -> OpenCV ``distCoeffs = (k1, k2, p1, p2, k3)``;
- ``R`` -> ``rvec = cv2.Rodrigues(R)[0]``; ``t`` -> ``tvec``; ``A`` -> ``cameraMatrix`` (zero
  skew: ``cv2.projectPoints`` reads only fx, fy, cx, cy);
- ``rotation_matrix(roll, pitch, yaw)`` -> ``Rotation.from_euler("xyz", [roll, pitch, yaw])``;
- ``decompose_projection(P)`` -> ``cv2.decomposeProjectionMatrix(P)``: same A (after dividing
  by K[2, 2]) and R for P = λ·A[R|t] with λ > 0; OpenCV returns the camera centre C = −Rᵀt as
  a homogeneous 4-vector instead of t, and does not fix the sign of λ < 0 (its K[2, 2] < 0);
- ``undistort_points(xd, k, p, n)`` -> ``cv2.undistortPoints(xd, I, distCoeffs,
  criteria=(COUNT, n, 0))`` (the same fixed-point iteration).
"""
from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST, raises_naming
from scipy.spatial.transform import Rotation

import cvkit
from cvkit import camera, registry

cv2 = pytest.importorskip("cv2")


def _rng(seed=0):
    return np.random.default_rng(seed)


def _random_camera(rng, skew=0.0):
    fu = rng.uniform(300, 3000)
    A = camera.intrinsic_matrix(fu, fu * rng.uniform(0.8, 1.2), rng.uniform(100, 900), rng.uniform(100, 700), skew)
    R = camera.rotation_matrix(*rng.uniform(-np.pi, np.pi, 3))
    t = rng.normal(0, 1, 3) + np.array([0, 0, 6.0])
    return A, R, t


def _points_in_front(rng, R, t, n=40, depth=(1.0, 20.0), spread=0.5):
    z = rng.uniform(*depth, n)
    cam = np.column_stack([rng.uniform(-spread, spread, (n, 2)) * z[:, None], z])
    return (cam - t) @ R


def _cv2_distortion(k, p):
    k = list(k) + [0.0] * (3 - len(k))
    return np.array([k[0], k[1], p[0], p[1], k[2]], dtype=np.float64)


def _cv2_project(X, A, R, t, k=(0.0,), p=(0.0, 0.0)):
    rvec, _ = cv2.Rodrigues(np.asarray(R, dtype=np.float64))
    out, _ = cv2.projectPoints(np.asarray(X, dtype=np.float64), rvec, np.asarray(t, dtype=np.float64),
                               np.asarray(A, dtype=np.float64), _cv2_distortion(k, p))
    return out[:, 0]


K_SETS = [(-0.3, 0.1, -0.02), (0.3, -0.1, 0.02), (0.25, 0.05), (-0.12,), (0.0,)]
P_SETS = [(0.0, 0.0), (0.002, -0.0015), (-0.002, 0.002)]


# --------------------------------------------------------------------------------------------
# homogeneous coordinates
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("d", [1, 2, 3, 4])
def test_to_and_from_homogeneous_match_opencv(d):
    pts = _rng(d).normal(0, 10, (15, d))
    if d in (2, 3):  # OpenCV converts 2-D and 3-D points only
        want = cv2.convertPointsToHomogeneous(pts)[:, 0]
        np.testing.assert_array_equal(camera.to_homogeneous(pts), want)
    h = camera.to_homogeneous(pts) * _rng(d + 10).uniform(0.5, 3, (15, 1)) * _rng(3).choice([-1, 1], (15, 1))
    np.testing.assert_allclose(camera.from_homogeneous(h), pts, rtol=1e-14, atol=1e-13)
    if d + 1 in (3, 4):
        want = cv2.convertPointsFromHomogeneous(h)[:, 0]
        np.testing.assert_allclose(camera.from_homogeneous(h), want, rtol=1e-14, atol=1e-13)


def test_homogeneous_shapes_dtypes_and_single_points():
    out = camera.to_homogeneous(np.array([[1, 2], [3, 4]], dtype=np.uint8))
    assert out.dtype == np.float64 and out.tolist() == [[1, 2, 1], [3, 4, 1]]
    assert camera.to_homogeneous([5, 6, 7]).tolist() == [5, 6, 7, 1]
    assert camera.from_homogeneous([6, 3, 3]).tolist() == [2, 1]
    assert camera.to_homogeneous(np.zeros((0, 2))).shape == (0, 3)
    assert camera.from_homogeneous(np.zeros((0, 3))).shape == (0, 2)
    assert camera.from_homogeneous(np.array([[7, 2, 2]])).dtype == np.float64


def test_equivalence_class_gives_one_point():
    """[ku, kv, k] ≡ [u, v, 1] for every k ≠ 0 (§7.4.1)."""
    m = np.array([3.5, -2.0, 1.0])
    ks = np.array([1e-9, -1e-9, 0.3, -7.0, 1e9])
    np.testing.assert_allclose(camera.from_homogeneous(ks[:, None] * m), np.tile(m[:2], (5, 1)), rtol=1e-14)


def test_points_at_infinity_follow_np_divide_without_warnings():
    h = np.array([[2.0, -1.0, 0.0], [0.0, 0.0, 0.0], [-3.0, 0.0, 0.0], [1.0, 1.0, -0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = camera.from_homogeneous(h)
    with np.errstate(all="ignore"):
        want = np.divide(h[:, :2], h[:, 2:])
    np.testing.assert_array_equal(out, want)
    assert out[0].tolist() == [np.inf, -np.inf] and np.isnan(out[1]).all() and out[3].tolist() == [-np.inf, -np.inf]


def test_limit_of_a_moving_point_is_its_point_at_infinity():
    """§7.4.2: [x0 + λa, y0 + λb, 1] ≡ [x0/λ + a, y0/λ + b, 1/λ] → [a, b, 0] as λ → ∞."""
    start, direction = np.array([2.0, -1.0]), np.array([3.0, 4.0])
    for lam in (1e2, 1e4, 1e6):
        h = camera.to_homogeneous(start + lam * direction) / lam
        assert np.abs(h - np.r_[direction, 0.0]).max() <= 3.0 / lam


# --------------------------------------------------------------------------------------------
# intrinsics, rotations, extrinsics, the PPM
# --------------------------------------------------------------------------------------------
def test_intrinsic_matrix_layout():
    A = camera.intrinsic_matrix(800, 780, 320.5, 240.25, skew=1.5)
    np.testing.assert_array_equal(A, [[800, 1.5, 320.5], [0, 780, 240.25], [0, 0, 1]])
    assert A.dtype == np.float64
    # u = fu x/z + s y/z + u0, v = fv y/z + v0 (§7.2.3)
    x, y, z = 0.3, -0.2, 2.0
    np.testing.assert_allclose(A @ [x / z, y / z, 1], [800 * x / z + 1.5 * y / z + 320.5, 780 * y / z + 240.25, 1])


@pytest.mark.parametrize("seed", range(6))
def test_rotation_matrix_matches_scipy_and_is_a_rotation(seed):
    roll, pitch, yaw = _rng(seed).uniform(-4, 4, 3)
    R = camera.rotation_matrix(roll, pitch, yaw)
    np.testing.assert_allclose(R, Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(R, Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)


def test_rotation_matrix_elementary_rotations_are_active():
    quarter = np.pi / 2
    np.testing.assert_allclose(camera.rotation_matrix(quarter, 0, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-15)  # y -> z
    np.testing.assert_allclose(camera.rotation_matrix(0, quarter, 0) @ [0, 0, 1], [1, 0, 0], atol=1e-15)  # z -> x
    np.testing.assert_allclose(camera.rotation_matrix(0, 0, quarter) @ [1, 0, 0], [0, 1, 0], atol=1e-15)  # x -> y
    a, b, c = 0.3, -0.5, 1.1
    Rx, Ry, Rz = (camera.rotation_matrix(a, 0, 0), camera.rotation_matrix(0, b, 0), camera.rotation_matrix(0, 0, c))
    np.testing.assert_allclose(camera.rotation_matrix(a, b, c), Rz @ Ry @ Rx, atol=1e-15)
    assert np.abs(camera.rotation_matrix(a, b, c) - Rx @ Ry @ Rz).max() > 0.1  # order matters


def test_extrinsic_matrix_moves_points_and_inverts_as_a_rigid_motion():
    rng = _rng(1)
    R = camera.rotation_matrix(*rng.uniform(-3, 3, 3))
    t = rng.normal(0, 2, 3)
    G = camera.extrinsic_matrix(R, t.reshape(3, 1))
    X = rng.normal(0, 3, (10, 3))
    np.testing.assert_allclose(camera.to_homogeneous(X) @ G.T, camera.to_homogeneous(X @ R.T + t), atol=1e-13)
    np.testing.assert_array_equal(G[3], [0, 0, 0, 1])
    G_inv = camera.extrinsic_matrix(R.T, -R.T @ t)
    np.testing.assert_allclose(G_inv @ G, np.eye(4), atol=1e-14)


@pytest.mark.parametrize("seed", range(4))
def test_projection_matrix_factorisations(seed):
    """P = A[I|0]G = A[R|t] (§7.6.1), and it projects like OpenCV without distortion."""
    rng = _rng(seed)
    A, R, t = _random_camera(rng)
    P = camera.projection_matrix(A, R, list(t))
    G = camera.extrinsic_matrix(R, t)
    np.testing.assert_allclose(P, A @ np.eye(3, 4) @ G, rtol=1e-15, atol=1e-12)
    np.testing.assert_allclose(P, A @ np.column_stack([R, t]), rtol=1e-15, atol=1e-12)
    X = _points_in_front(rng, R, t)
    np.testing.assert_allclose(camera.project(P, X), _cv2_project(X, A, R, t), rtol=0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# projection
# --------------------------------------------------------------------------------------------
def test_project_is_the_nonlinear_formula_of_the_notes():
    """Equation (1) of §7.3 written out, and invariance to the scale of P."""
    rng = _rng(2)
    A, R, t = _random_camera(rng)
    X = _points_in_front(rng, R, t)
    cam = X @ R.T + t
    want = np.column_stack([A[0, 0] * cam[:, 0] / cam[:, 2] + A[0, 2], A[1, 1] * cam[:, 1] / cam[:, 2] + A[1, 2]])
    P = camera.projection_matrix(A, R, t)
    for scale in (1.0, -3.0, 1e-8, 2e7):
        np.testing.assert_allclose(camera.project(scale * P, X), want, rtol=1e-12, atol=1e-9)
    w = rng.uniform(0.1, 5, 40) * rng.choice([-1, 1], 40)
    np.testing.assert_allclose(camera.project(P, camera.to_homogeneous(X) * w[:, None]), want, rtol=1e-12, atol=1e-9)


def test_vanishing_point_is_the_limit_of_far_points_and_shared_by_parallel_lines():
    rng = _rng(3)
    A, R, t = _random_camera(rng)
    P = camera.projection_matrix(A, R, t)
    d = np.array([0.3, -0.2, 1.0])
    vp = camera.project(P, [np.r_[d, 0.0]])[0]
    np.testing.assert_allclose(vp, camera.project(camera.projection_matrix(A, R, np.zeros(3)), [d])[0], rtol=1e-12)
    starts = rng.normal(0, 2, (5, 3))
    for lam in (1e3, 1e6, 1e9):
        far = camera.project(P, starts + lam * d)
        assert np.abs(far - vp).max() < 1e6 / lam   # converges like 1/λ
    # a direction parallel to the image plane has its vanishing point at infinity
    P0 = camera.projection_matrix(A, np.eye(3), [0, 0, 5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = camera.project(P0, [[1.0, 0.0, 0.0, 0.0]])
    assert out[0, 0] == np.inf and np.isnan(out[0, 1])


def test_project_accepts_integer_and_empty_input():
    P = camera.projection_matrix(camera.intrinsic_matrix(100, 100, 50, 40), np.eye(3), [0, 0, 2])
    np.testing.assert_allclose(camera.project(P.astype(int), np.array([[1, 2, 2]])), [[75, 90]])
    assert camera.project(P, np.zeros((0, 3))).shape == (0, 2)


# --------------------------------------------------------------------------------------------
# decomposition
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(12))
def test_decompose_projection_recovers_random_cameras(seed):
    rng = _rng(100 + seed)
    A, R, t = _random_camera(rng, skew=rng.uniform(-5, 5) if seed % 2 else 0.0)
    scale = float(np.exp(rng.uniform(-12, 12))) * (-1) ** seed
    A2, R2, t2 = camera.decompose_projection(scale * camera.projection_matrix(A, R, t))
    np.testing.assert_allclose(A2, A, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(R2, R, atol=1e-12)
    np.testing.assert_allclose(t2, t, rtol=1e-10, atol=1e-11)
    assert t2.shape == (3,) and A2[2, 2] == 1.0 and np.all(np.diag(A2) > 0)
    assert np.linalg.det(R2) == pytest.approx(1.0, abs=1e-12)
    assert A2[1, 0] == A2[2, 0] == A2[2, 1] == 0.0


@pytest.mark.parametrize("seed", range(6))
def test_decompose_projection_agrees_with_opencv(seed):
    rng = _rng(200 + seed)
    A, R, t = _random_camera(rng)
    P = rng.uniform(0.01, 100) * camera.projection_matrix(A, R, t)
    A2, R2, t2 = camera.decompose_projection(P)
    K, Rcv, C = cv2.decomposeProjectionMatrix(P)[:3]
    np.testing.assert_allclose(A2, K / K[2, 2], rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(R2, Rcv, atol=1e-12)
    np.testing.assert_allclose(-R2.T @ t2, C[:3, 0] / C[3, 0], rtol=1e-10, atol=1e-10)
    # OpenCV does not fix the sign of a negative multiple: its K[2, 2] is negative then
    K_neg, R_neg = cv2.decomposeProjectionMatrix(-P)[:2]
    assert K_neg[2, 2] < 0 and np.linalg.det(R_neg) > 0
    A3, R3, t3 = camera.decompose_projection(-P)
    np.testing.assert_allclose(A3, A2, rtol=1e-12)
    np.testing.assert_allclose(R3, R2, atol=1e-14)


def test_decompose_projection_null_vector_is_the_camera_centre():
    rng = _rng(4)
    A, R, t = _random_camera(rng)
    P = camera.projection_matrix(A, R, t)
    _, R2, t2 = camera.decompose_projection(P)
    centre = -R2.T @ t2
    np.testing.assert_allclose(P @ np.r_[centre, 1.0], 0.0, atol=1e-9)


def test_decompose_projection_of_a_general_matrix_reproduces_it():
    """Any P with an invertible left block is λ·A[R|t] of some camera (with skew)."""
    P = _rng(5).normal(0, 1, (3, 4))
    A, R, t = camera.decompose_projection(P)
    P2 = camera.projection_matrix(A, R, t)
    ratio = P[0, 0] / P2[0, 0]
    np.testing.assert_allclose(P, ratio * P2, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("P", [np.zeros((3, 4)), np.column_stack([np.ones((3, 3)), np.ones(3)]),
                               np.array([[1.0, 0, 0, 1], [0, 1, 0, 2], [1, 1, 0, 3]])])
def test_decompose_projection_refuses_singular_blocks(P):
    with pytest.raises(ValueError, match="P"):
        camera.decompose_projection(P)


# --------------------------------------------------------------------------------------------
# distortion
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("k", "p"), list(itertools.product(K_SETS, P_SETS)))
def test_distort_matches_opencv(k, p):
    xy = _rng(6).uniform(-0.6, 0.6, (50, 2))
    want = _cv2_project(camera.to_homogeneous(xy), np.eye(3), np.eye(3), np.zeros(3), k, p)
    np.testing.assert_allclose(camera.distort(xy, k, p), want, rtol=0, atol=1e-14)


def test_distort_defaults_scalar_k_and_barrel_pincushion():
    xy = _rng(7).uniform(-0.5, 0.5, (30, 2))
    np.testing.assert_array_equal(camera.distort(xy), xy)
    np.testing.assert_array_equal(camera.distort(xy, 0.1, (0, 0)), camera.distort(xy, (0.1, 0.0, 0.0), [0, 0]))
    r = np.hypot(*xy.T)
    assert np.all(np.hypot(*camera.distort(xy, (-0.2,)).T) <= r)   # barrel pulls in
    assert np.all(np.hypot(*camera.distort(xy, (0.2,)).T) >= r)    # pincushion pushes out


def test_tangential_displacement_has_radial_and_tangential_parts():
    """Δ·r̂ = 3r(p1 y + p2 x) and Δ·t̂ = r(p1 x − p2 y) (documented in ``distort``)."""
    xy = _rng(8).uniform(-0.5, 0.5, (40, 2))
    p1, p2 = 0.003, -0.002
    delta = camera.distort(xy, (0.0,), (p1, p2)) - xy
    x, y = xy.T
    r = np.hypot(x, y)
    np.testing.assert_allclose((delta * xy).sum(1) / r, 3 * r * (p1 * y + p2 * x), atol=1e-15)
    np.testing.assert_allclose((delta * np.column_stack([-y, x])).sum(1) / r, r * (p1 * x - p2 * y), atol=1e-15)


@pytest.mark.filterwarnings("ignore::cvkit.camera.ConvergenceWarning")  # few steps: far from the inverse, said
@pytest.mark.parametrize("iterations", [0, 1, 3, 20])
@pytest.mark.parametrize(("k", "p"), [((-0.3, 0.1, -0.02), (0.002, -0.001)), ((0.2,), (0.0, 0.001))])
def test_undistort_points_matches_opencv_iteration_by_iteration(k, p, iterations):
    xd = _rng(9).uniform(-0.4, 0.4, (60, 2))
    got = camera.undistort_points(xd, k, p, iterations)
    if iterations == 0:
        np.testing.assert_array_equal(got, xd)
        return
    want = cv2.undistortPoints(xd[:, None, :], np.eye(3), _cv2_distortion(k, p),
                               criteria=(cv2.TERM_CRITERIA_COUNT, iterations, 0))[:, 0]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def test_undistort_points_inverts_distort_to_1e_12_on_the_stated_range():
    """Ideal points with |x|, |y| ≤ 0.4 and every corner of |k1| ≤ 0.3, |k2| ≤ 0.1,
    |k3| ≤ 0.02, |p| ≤ 0.002: error ≤ 1e-12 in normalised units, ≤ 1e-9 px for f ≤ 1000 px."""
    g = np.linspace(-0.4, 0.4, 17)
    ideal = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    worst = 0.0
    for k1, k2, k3, p1, p2 in itertools.product((-0.3, 0.3), (-0.1, 0.1), (-0.02, 0.02), (-0.002, 0.002), (-0.002, 0.002)):
        k, p = (k1, k2, k3), (p1, p2)
        back = camera.undistort_points(camera.distort(ideal, k, p), k, p)
        worst = max(worst, float(np.abs(back - ideal).max()))
    assert worst <= 1e-12, worst


def test_undistort_points_with_strong_barrel_at_distorted_corners_needs_more_steps():
    """Documented limit: distorted points filling |x|, |y| ≤ 0.4 with all k < 0."""
    g = np.linspace(-0.4, 0.4, 17)
    xd = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    k, p = (-0.3, -0.1, -0.02), (-0.002, -0.002)
    residual = np.abs(camera.distort(camera.undistort_points(xd, k, p), k, p) - xd).max()
    assert 1e-12 < residual < 1e-7
    assert np.abs(camera.distort(camera.undistort_points(xd, k, p, 40), k, p) - xd).max() < 1e-14


# --------------------------------------------------------------------------------------------
# the full pipeline
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("k", "p"), list(itertools.product(K_SETS, P_SETS)))
def test_project_full_matches_opencv_project_points(k, p):
    rng = _rng(10)
    A, R, t = _random_camera(rng)
    X = _points_in_front(rng, R, t, 80, spread=0.45)
    np.testing.assert_allclose(camera.project_full(X, A, R, t, k, p), _cv2_project(X, A, R, t, k, p), rtol=0, atol=1e-9)


def test_project_full_is_the_four_steps_and_reduces_to_project():
    rng = _rng(11)
    A, R, t = _random_camera(rng, skew=2.5)
    X = _points_in_front(rng, R, t, 30)
    k, p = (-0.2, 0.05, -0.01), (0.001, 0.0015)
    cam = camera.from_homogeneous(camera.to_homogeneous(X) @ camera.extrinsic_matrix(R, t).T)   # 1
    normalized = cam[:, :2] / cam[:, 2:]                                                        # 2
    distorted = camera.distort(normalized, k, p)                                                # 3
    pixels = camera.from_homogeneous(camera.to_homogeneous(distorted) @ A.T)                    # 4
    np.testing.assert_allclose(camera.project_full(X, A, R, t, k, p), pixels, rtol=1e-12, atol=1e-9)
    P = camera.projection_matrix(A, R, t)
    np.testing.assert_allclose(camera.project_full(X, A, R, t), camera.project(P, X), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(camera.project_full(X, 3.0 * A, R, t, k, p), pixels, rtol=1e-12, atol=1e-9)


def test_project_full_point_on_the_focal_plane_and_empty_input():
    A = camera.intrinsic_matrix(500, 500, 320, 240)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = camera.project_full([[1.0, 0.0, 0.0], [0.2, 0.1, 2.0]], A, np.eye(3), [0, 0, 0], (-0.1,), (0.001, 0.0))
    assert out[0, 0] == np.inf and np.isnan(out[0, 1]) and np.all(np.isfinite(out[1]))
    assert camera.project_full(np.zeros((0, 3)), A, np.eye(3), [0, 0, 1]).shape == (0, 2)


# --------------------------------------------------------------------------------------------
# registry: pipelines use the active provider's building blocks; inputs are never modified
# --------------------------------------------------------------------------------------------
@pytest.fixture
def clean_student():
    yield registry.provider("student")
    registry.provider("student").clear()


def test_pipelines_call_building_blocks_through_the_registry(clean_student):
    calls = []

    @registry.student("camera.distort")
    def my_distort(xy_normalized, k=(0, 0, 0), p=(0, 0)):
        calls.append("distort")
        return np.asarray(xy_normalized, dtype=float) * 2.0

    @registry.student("camera.extrinsic_matrix")
    def my_extrinsic(R, t):
        calls.append("extrinsic")
        return np.eye(4)

    @registry.student("camera.from_homogeneous")
    def my_from_h(points_h):
        calls.append("from_homogeneous")
        return np.zeros((len(points_h), 2))

    A, R, t = camera.intrinsic_matrix(100, 100, 50, 40), np.eye(3), np.array([0, 0, 2.0])
    X = np.array([[0.2, 0.4, 0.0]])
    normal = camera.project_full(X, A, R, t, (-0.1,), (0, 0))
    with cvkit.use("student"):
        np.testing.assert_allclose(camera.project_full(X, A, R, t, (-0.1,), (0, 0)), [[50 + 100 * 0.2, 40 + 100 * 0.4]])
        np.testing.assert_array_equal(camera.projection_matrix(A, R, t), A @ np.eye(3, 4))
        np.testing.assert_array_equal(camera.project(np.eye(3, 4), X), [[0.0, 0.0]])
    assert calls == ["distort", "extrinsic", "from_homogeneous"]
    np.testing.assert_array_equal(camera.project_full(X, A, R, t, (-0.1,), (0, 0)), normal)


def test_inputs_are_never_modified():
    rng = _rng(12)
    A, R, t = _random_camera(rng, skew=1.0)
    X = _points_in_front(rng, R, t, 10)
    P = camera.projection_matrix(A, R, t)
    xy = rng.uniform(-0.3, 0.3, (10, 2))
    k, p = np.array([-0.2, 0.05, 0.01]), np.array([0.001, 0.002])
    args = [A, R, t, X, P, xy, k, p]
    copies = [a.copy() for a in args]
    camera.to_homogeneous(X)
    camera.from_homogeneous(camera.to_homogeneous(X))
    camera.extrinsic_matrix(R, t)
    camera.project(P, X)
    camera.decompose_projection(P)
    camera.undistort_points(camera.distort(xy, k, p), k, p)
    camera.project_full(X, A, R, t, k, p)
    for a, c in zip(args, copies):
        np.testing.assert_array_equal(a, c)


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------
GOOD_A = camera.intrinsic_matrix(500, 500, 320, 240)
GOOD_P = camera.projection_matrix(GOOD_A, np.eye(3), [0, 0, 4])


@FAST
@given(shape=st.tuples(st.integers(0, 4), st.integers(0, 5)).filter(lambda s: s[1] not in (2,)))
def test_point_functions_refuse_wrong_point_shapes(shape):
    bad = np.zeros(shape)
    raises_naming(ValueError, "xy_normalized", camera.distort, bad, (0.1,), (0, 0))
    raises_naming(ValueError, "xy_distorted", camera.undistort_points, bad, (0.1,), (0, 0))
    if shape[1] not in (3, 4):
        raises_naming(ValueError, "points_world", camera.project, GOOD_P, bad)
    if shape[1] != 3:
        raises_naming(ValueError, "points_world", camera.project_full, bad, GOOD_A, np.eye(3), [0, 0, 1])


@FAST
@given(ndim=st.sampled_from([0, 3]))
def test_homogeneous_refuse_wrong_dimensions(ndim):
    bad = np.ones((2,) * ndim)
    raises_naming(ValueError, "points", camera.to_homogeneous, bad)
    raises_naming(ValueError, "points_h", camera.from_homogeneous, bad)


def test_homogeneous_refuse_too_few_coordinates_and_non_finite():
    raises_naming(ValueError, "points", camera.to_homogeneous, np.zeros((3, 0)))
    raises_naming(ValueError, "points_h", camera.from_homogeneous, np.zeros((3, 1)))
    raises_naming(ValueError, "points", camera.to_homogeneous, [[np.inf, 1.0]])
    raises_naming(ValueError, "points_h", camera.from_homogeneous, [[np.nan, 1.0, 1.0]])
    raises_naming(TypeError, "points", camera.to_homogeneous, "1, 2")
    raises_naming(TypeError, "points_h", camera.from_homogeneous, [[1 + 2j, 1.0, 1.0]])


@FAST
@given(which=st.sampled_from(["fu", "fv"]), value=st.one_of(st.floats(max_value=0.0), st.just(np.nan), st.just(np.inf)))
def test_intrinsic_matrix_refuses_bad_focal_lengths(which, value):
    kwargs = {"fu": 500.0, "fv": 500.0, "u0": 320.0, "v0": 240.0, which: value}
    raises_naming(ValueError, which, camera.intrinsic_matrix, **kwargs)


def test_scalar_arguments_must_be_real_numbers():
    raises_naming(TypeError, "u0", camera.intrinsic_matrix, 500, 500, "320", 240)
    raises_naming(TypeError, "skew", camera.intrinsic_matrix, 500, 500, 320, 240, skew=None)
    raises_naming(TypeError, "yaw", camera.rotation_matrix, 0.1, 0.2, [0.3])
    raises_naming(ValueError, "pitch", camera.rotation_matrix, 0.1, np.nan, 0.3)
    raises_naming(TypeError, "iterations", camera.undistort_points, np.zeros((2, 2)), (0.1,), (0, 0), 2.5)
    raises_naming(ValueError, "iterations", camera.undistort_points, np.zeros((2, 2)), (0.1,), (0, 0), -1)


@FAST
@given(angles=st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3)),
       noise=st.floats(1e-2, 0.5), flip=st.booleans())
def test_non_rotations_are_refused(angles, noise, flip):
    """R + n·J (J the anti-identity) is off by at least about 2n/3 in RᵀR − I (RᵀJ + JᵀR has
    the eigenvalue −2), so n ≥ 0.01 is beyond the 1e-3 tolerance."""
    R = camera.rotation_matrix(*angles)
    bad = R @ np.diag([-1.0, 1.0, 1.0]) if flip else R + noise * np.eye(3)[::-1]
    raises_naming(ValueError, "R", camera.extrinsic_matrix, bad, [0, 0, 1])
    raises_naming(ValueError, "R", camera.projection_matrix, GOOD_A, bad, [0, 0, 1])
    raises_naming(ValueError, "R", camera.project_full, np.ones((2, 3)), GOOD_A, bad, [0, 0, 1])


def test_a_rotation_typed_with_three_decimals_is_used_as_given():
    """cos 30° typed as 0.866 (RᵀR off by 4e-5) or cos 45° as 0.707 (2e-4) is a rotation to
    the reader: accepted, and the matrices are made with the entries given."""
    for c, s in ((0.866, 0.5), (0.707, 0.707)):
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        G = camera.extrinsic_matrix(R, [1.0, 2.0, 3.0])
        np.testing.assert_array_equal(G[:3, :3], R)
        np.testing.assert_allclose(camera.projection_matrix(GOOD_A, R, [1.0, 2.0, 3.0]),
                                   GOOD_A @ np.hstack([R, [[1.0], [2.0], [3.0]]]), rtol=1e-15)
    raises_naming(ValueError, "R", camera.extrinsic_matrix, 1.002 * np.eye(3), [0, 0, 1])  # a 0.2 % scale: 4e-3


@pytest.mark.parametrize("t", [[0, 0], np.zeros((3, 3)), np.zeros(4), [0, np.nan, 1]])
def test_bad_translations_are_refused(t):
    raises_naming(ValueError, "t", camera.extrinsic_matrix, np.eye(3), t)
    raises_naming(ValueError, "t", camera.projection_matrix, GOOD_A, np.eye(3), t)


@pytest.mark.parametrize("A", [GOOD_A.T, np.zeros((3, 3)), np.diag([500.0, 0.0, 1.0]), np.eye(4), np.ones(3)])
def test_bad_intrinsic_matrices_are_refused(A):
    raises_naming(ValueError, "A", camera.projection_matrix, A, np.eye(3), [0, 0, 1])
    raises_naming(ValueError, "A", camera.project_full, np.ones((2, 3)), A, np.eye(3), [0, 0, 1])


@pytest.mark.parametrize(("k", "p", "name"), [((), (0, 0), "k"), ((0.1, 0.2, 0.3, 0.4), (0, 0), "k"),
                                              ((0.1,), (0.0,), "p"), ((0.1,), (0, 0, 0), "p"),
                                              ((np.nan,), (0, 0), "k"), ((0.1,), (0, np.inf), "p"),
                                              ("abc", (0, 0), "k"), ((0.1,), None, "p")])
def test_bad_distortion_coefficients_are_refused(k, p, name):
    exc = TypeError if isinstance(k, str) or p is None else ValueError
    raises_naming(exc, name, camera.distort, np.zeros((2, 2)), k, p)
    raises_naming(exc, name, camera.undistort_points, np.zeros((2, 2)), k, p)
    raises_naming(exc, name, camera.project_full, np.ones((2, 3)), GOOD_A, np.eye(3), [0, 0, 1], k, p)


@FAST
@given(shape=st.tuples(st.integers(1, 5), st.integers(1, 5)).filter(lambda s: s != (3, 4)))
def test_bad_projection_matrices_are_refused(shape):
    raises_naming(ValueError, "P", camera.project, np.ones(shape), np.zeros((2, 3)))
    raises_naming(ValueError, "P", camera.decompose_projection, np.ones(shape))


def test_zero_and_non_finite_projection_matrices_are_refused():
    raises_naming(ValueError, "P", camera.project, np.zeros((3, 4)), np.ones((2, 3)))
    raises_naming(ValueError, "P", camera.decompose_projection, np.full((3, 4), np.nan))
