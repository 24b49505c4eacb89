"""Chapter 8 warping (cvkit.warp) against SciPy / scikit-image / OpenCV oracles and its own definitions.

Parameter mappings (cvkit -> oracle):
- ``bilinear_sample(img, x, y, fill)`` -> ``scipy.ndimage.map_coordinates(img, [y, x], order=1,
  mode="constant", cval=fill)`` (SciPy takes (row, col));
- ``warp_homography(img, H, shape, fill)`` -> ``skimage.transform.warp(img,
  ProjectiveTransform(H).inverse, output_shape=shape, order=1, cval=fill)`` and, away from the
  border, ``cv2.warpPerspective(img, H, (cols, rows), flags=INTER_LINEAR)`` (OpenCV interpolates
  with 5-bit fixed-point weights: agreement to ~1e-3 of the contrast);
- ``undistort_image(img, A, k, p)`` -> ``cv2.undistort(img, A, (k1, k2, p1, p2, k3))``;
- ``birds_eye_homography(img_pts, ground, s)`` -> ``cv2.getPerspectiveTransform(img_pts, ground·s)``.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.ndimage
from hypothesis import given
from hypothesis import strategies as st
from input_helpers import FAST

from cvkit import calibration, camera, data, warp

cv2 = pytest.importorskip("cv2")
skimage_transform = pytest.importorskip("skimage.transform")


def _image(shape=(40, 50), seed=0, color=False):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    base = 0.5 + 0.3 * np.sin(0.3 * x + 0.2 * y) + 0.1 * rng.random(shape)
    if color:
        return np.stack([base, base[::-1], 1 - base], axis=-1)
    return base


def _map(H, pts):
    m = np.column_stack([pts, np.ones(len(pts))]) @ np.asarray(H).T
    return m[:, :2] / m[:, 2:]


H_PERSPECTIVE = np.array([[0.95, -0.2, 6.0], [0.15, 1.05, -3.0], [6e-4, -4e-4, 1.0]])


# --------------------------------------------------------------------------------------------
# bilinear sampling
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("fill", [0.0, -2.5, 7.0])
def test_bilinear_sample_equals_map_coordinates(fill):
    rng = np.random.default_rng(1)
    img = _image((7, 9))
    x = np.concatenate([rng.uniform(-1.5, 9.5, 300), [0.0, 8.0, 8.0, 0.0, 8.0 + 1e-9, -1e-9]])
    y = np.concatenate([rng.uniform(-1.5, 7.5, 300), [0.0, 6.0, 0.0, 6.0, 3.0, 2.0]])
    want = scipy.ndimage.map_coordinates(img, [y, x], order=1, mode="constant", cval=fill)
    np.testing.assert_allclose(warp.bilinear_sample(img, x, y, fill=fill), want, rtol=0, atol=1e-12)


def test_bilinear_sample_colour_shapes_and_exact_pixels():
    img = _image((6, 8), color=True)
    x, y = np.meshgrid(np.arange(8.0), np.arange(6.0))
    np.testing.assert_array_equal(warp.bilinear_sample(img, x, y), img)            # integer positions: the pixels
    grid = warp.bilinear_sample(img, np.full((2, 3), 1.5), np.full((2, 3), 2.25))
    assert grid.shape == (2, 3, 3)
    np.testing.assert_allclose(grid[0, 0], 0.75 * (img[2, 1] + img[2, 2]) / 2 + 0.25 * (img[3, 1] + img[3, 2]) / 2)
    assert np.isnan(warp.bilinear_sample(img, [np.nan], [1.0], fill=np.nan)).all()
    u8 = (img * 200).astype(np.uint8)
    assert warp.bilinear_sample(u8, 2.0, 3.0).dtype == np.float64
    np.testing.assert_array_equal(warp.bilinear_sample(u8, 2.0, 3.0), u8[3, 2].astype(float))


def test_bilinear_sample_inside_is_exactly_the_closed_pixel_range():
    img = np.arange(20.0).reshape(4, 5)
    for x, y, inside in [(0.0, 1.0, True), (4.0, 3.0, True), (-1e-16, 1.0, False), (1.0, -1e-300, False),
                         (4.0 + 1e-15, 1.0, False), (2.0, 3.0 + 4e-16, False)]:
        got = warp.bilinear_sample(img, [x], [y], fill=-1.0)[0]
        want = scipy.ndimage.map_coordinates(img, [[y], [x]], order=1, mode="constant", cval=-1.0)[0]
        assert (got != -1.0) == inside and got == pytest.approx(want), (x, y, got, want)


def test_bilinear_sample_is_linear_in_the_image_and_exact_on_planes():
    a, b = _image((5, 6), 1), _image((5, 6), 2)
    x, y = np.random.default_rng(0).uniform(0, 4, (2, 50))
    np.testing.assert_allclose(warp.bilinear_sample(2 * a - 3 * b, x, y),
                               2 * warp.bilinear_sample(a, x, y) - 3 * warp.bilinear_sample(b, x, y), atol=1e-12)
    rows, cols = np.mgrid[0:5, 0:6].astype(float)
    plane = 3 * cols - 2 * rows + 1
    np.testing.assert_allclose(warp.bilinear_sample(plane, x, y), 3 * x - 2 * y + 1, atol=1e-12)


# --------------------------------------------------------------------------------------------
# warping through a homography
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("color", [False, True])
def test_warp_homography_equals_skimage_away_from_the_border(color):
    """Inside, identical; skimage's "constant" mode also interpolates up to half a pixel beyond
    the outer pixel centres (towards cval), where cvkit (like SciPy's map_coordinates) fills."""
    img = _image(color=color)
    for H, shape, fill in ((H_PERSPECTIVE, (45, 55), 0.0), (np.diag([1.7, 0.8, 1.0]), (30, 90), 0.3)):
        ours = warp.warp_homography(img, H, shape, fill=fill)
        theirs = skimage_transform.warp(img, skimage_transform.ProjectiveTransform(H).inverse, output_shape=shape,
                                        order=1, cval=fill, mode="constant", preserve_range=True)
        inside = np.isfinite(warp.warp_homography(np.ones(img.shape[:2]), H, shape, fill=np.nan))
        assert inside.sum() > 500
        np.testing.assert_allclose(ours[inside], theirs[inside], atol=1e-10)
        assert np.all(ours[~inside] == fill)


def test_warp_homography_equals_opencv_away_from_the_border():
    img = _image().astype(np.float32)
    ours = warp.warp_homography(img, H_PERSPECTIVE, (45, 55))
    theirs = cv2.warpPerspective(img, H_PERSPECTIVE, (55, 45), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    inside = np.isfinite(warp.warp_homography(np.ones_like(img), H_PERSPECTIVE, (45, 55), fill=np.nan))
    inside = scipy.ndimage.binary_erosion(inside, iterations=2)
    assert inside.sum() > 1000
    assert np.abs(ours - theirs)[inside].max() < 5e-3                 # 1/32-pixel weights in OpenCV


def test_warp_is_a_backward_map_without_holes_and_scale_does_not_matter():
    img = _image((20, 20))
    zoom = np.diag([2.5, 2.5, 1.0])
    out = warp.warp_homography(img, zoom, (50, 50), fill=np.nan)
    assert not np.isnan(out[:48, :48]).any()                          # no holes where the input is
    forward = np.full((50, 50), np.nan)                               # a forward map leaves most pixels empty
    yy, xx = np.mgrid[0:20, 0:20]
    forward[np.round(2.5 * yy).astype(int), np.round(2.5 * xx).astype(int)] = img
    assert np.isnan(forward[:48, :48]).mean() > 0.8
    np.testing.assert_allclose(warp.warp_homography(img, -3 * H_PERSPECTIVE, (20, 20)),
                               warp.warp_homography(img, H_PERSPECTIVE, (20, 20)), atol=1e-12)
    np.testing.assert_array_equal(warp.warp_homography(img, np.eye(3), (20, 20)), img)


def test_warp_then_inverse_warp_restores_the_interior():
    img = _image((40, 40))
    H = np.array([[1.0, 0.05, 1.5], [-0.04, 1.0, 2.0], [1e-4, 0.0, 1.0]])
    back = warp.warp_homography(warp.warp_homography(img, H, (40, 40)), np.linalg.inv(H), (40, 40))
    interior = (slice(8, 32), slice(8, 32))
    assert np.abs(back[interior] - img[interior]).mean() < 0.02        # two bilinear resamplings blur a little


# --------------------------------------------------------------------------------------------
# undistortion
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("k", "p"), [((-0.3, 0.1), (0.0, 0.0)), ((0.25,), (0.002, -0.003)),
                                      ((-0.2, 0.05, -0.01), (0.0, 0.001))])
def test_undistort_image_equals_opencv(k, p):
    img = _image((60, 80)).astype(np.float32)
    A = np.array([[70.0, 0.0, 41.0], [0.0, 72.0, 28.5], [0.0, 0.0, 1.0]])
    kk = list(k) + [0.0] * (3 - len(k))
    ours = warp.undistort_image(img, A, k, p)
    theirs = cv2.undistort(img, A, np.array([kk[0], kk[1], p[0], p[1], kk[2]]))
    inside = scipy.ndimage.binary_erosion(warp.undistort_image(np.ones((60, 80)), A, k, p) > 0.5, iterations=2)
    assert inside.mean() > 0.5
    assert np.abs(ours - theirs)[inside].max() < 5e-3


def test_undistorted_board_corners_are_the_distortion_free_projections():
    """The whole point of §8.4.1: after undistortion the corners sit where the pinhole model
    (no lens) puts them."""
    v = data.chessboard_views(n_views=1, image_size=(240, 320), A=[[400, 0, 160], [0, 410, 120], [0, 0, 1]],
                              k=(-0.25, 0.06), noise=0.0, rng=2)
    straight = warp.undistort_image(v.images[0], v.A, v.k)
    found = calibration.find_chessboard_corners(straight, 9, 6)
    ideal = camera.project(camera.projection_matrix(v.A, v.rotations[0], v.translations[0]), v.world_points)
    error = min(np.linalg.norm(found - ideal, axis=1).mean(), np.linalg.norm(found[::-1] - ideal, axis=1).mean())
    assert error < 0.1


def test_zero_distortion_is_the_identity():
    img = _image((10, 12), color=True)
    A = np.array([[20.0, 0.5, 6.0], [0.0, 21.0, 4.5], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(warp.undistort_image(img, A, (0.0,)), img, atol=1e-12)


# --------------------------------------------------------------------------------------------
# virtual cameras
# --------------------------------------------------------------------------------------------
def test_rotation_homography_maps_the_images_of_a_rotating_camera():
    """Whatever the depth of a point, the camera (A, I) and the rotated camera (A, R) see it at
    pixels related by H = A·R·A⁻¹."""
    rng = np.random.default_rng(3)
    A = camera.intrinsic_matrix(700.0, 690.0, 330.0, 235.0, 1.5)
    R = camera.rotation_matrix(0.1, -0.15, 0.2)
    points = np.column_stack([rng.uniform(-2, 2, (30, 2)), rng.uniform(2, 40, 30)])     # all depths
    before = camera.project(camera.projection_matrix(A, np.eye(3), np.zeros(3)), points)
    after = camera.project(camera.projection_matrix(A, R, np.zeros(3)), points)
    H = warp.rotation_homography(A, R)
    assert H[2, 2] == 1.0
    np.testing.assert_allclose(_map(H, before), after, atol=1e-9)


def test_birds_eye_homography_equals_opencvs_perspective_transform():
    image = np.array([[280.0, 400.0], [380.0, 405.0], [345.0, 300.0], [305.0, 298.0]])
    ground = np.array([[0.0, 0.0], [3.5, 0.0], [3.5, 12.0], [0.0, 12.0]])
    H = warp.birds_eye_homography(image, ground, 20.0)
    theirs = cv2.getPerspectiveTransform(image.astype(np.float32), (ground * 20).astype(np.float32))
    np.testing.assert_allclose(H, theirs / theirs[2, 2], rtol=1e-4, atol=1e-8)
    np.testing.assert_allclose(_map(H, image), ground * 20.0, atol=1e-9)


def test_birds_eye_view_of_a_rendered_plane_is_metric():
    """A chessboard lying on the 'road' and seen in perspective comes out square in the bird's-eye view."""
    v = data.chessboard_views(n_views=1, image_size=(240, 320), A=[[400, 0, 160], [0, 410, 120], [0, 0, 1]],
                              k=(0.0,), noise=0.0, rng=4, tilt=0.8)
    corners = v.image_points[0]
    picks = [0, 8, 53, 45]                                          # four outer inner corners
    H = warp.birds_eye_homography(corners[picks], v.world_points[picks, :2], 2.0)
    top = _map(H, corners) / 2.0
    np.testing.assert_allclose(top, v.world_points[:, :2], atol=1e-6)


# --------------------------------------------------------------------------------------------
# bad input (hypothesis)
# --------------------------------------------------------------------------------------------


@FAST
@given(shape=st.sampled_from([(5,), (4, 5, 2), (4, 5, 4), (2, 3, 4, 5)]))
def test_bilinear_sample_refuses_malformed_images(shape):
    with pytest.raises(ValueError, match="image"):
        warp.bilinear_sample(np.zeros(shape), [0.0], [0.0])


@FAST
@given(n=st.integers(1, 6), m=st.integers(1, 6))
def test_bilinear_sample_refuses_positions_that_do_not_broadcast(n, m):
    if n == m or 1 in (n, m):
        return
    with pytest.raises(ValueError, match="x and y"):
        warp.bilinear_sample(np.zeros((4, 4)), np.zeros(n), np.zeros(m))


def test_bilinear_sample_refuses_bad_fill_and_positions():
    with pytest.raises(TypeError, match="fill"):
        warp.bilinear_sample(np.zeros((4, 4)), [0.0], [0.0], fill="black")
    with pytest.raises(TypeError, match="x"):
        warp.bilinear_sample(np.zeros((4, 4)), ["a"], [0.0])


@FAST
@given(shape=st.one_of(st.just((0, 5)), st.just((5,)), st.just((5, 5, 5)), st.just((5, 2.5))))
def test_warp_refuses_bad_output_shapes(shape):
    with pytest.raises((ValueError, TypeError), match="output_shape"):
        warp.warp_homography(np.zeros((4, 4)), np.eye(3), shape)


def test_warp_refuses_singular_or_malformed_h():
    with pytest.raises(ValueError, match="invertible"):
        warp.warp_homography(np.zeros((4, 4)), np.ones((3, 3)), (4, 4))
    with pytest.raises(ValueError, match="H"):
        warp.warp_homography(np.zeros((4, 4)), np.eye(2), (4, 4))
    with pytest.raises(ValueError, match="H"):
        warp.warp_homography(np.zeros((4, 4)), np.full((3, 3), np.nan), (4, 4))


def test_undistort_and_virtual_cameras_refuse_bad_input():
    A = np.array([[20.0, 0.0, 5.0], [0.0, 20.0, 5.0], [0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="k"):
        warp.undistort_image(np.zeros((10, 10)), A, (0.1, 0.2, 0.3, 0.4))
    with pytest.raises(ValueError, match="p"):
        warp.undistort_image(np.zeros((10, 10)), A, (0.1,), (0.1,))
    with pytest.raises(ValueError, match="A"):
        warp.undistort_image(np.zeros((10, 10)), A.T, (0.1,))
    with pytest.raises(ValueError, match="R"):
        warp.rotation_homography(A, 2 * np.eye(3))
    with pytest.raises(ValueError, match="infinity"):
        warp.rotation_homography(np.eye(3), camera.rotation_matrix(0.0, np.pi / 2, 0.0))
    square = [[0, 0], [1, 0], [1, 1], [0, 1]]
    with pytest.raises(ValueError, match="collinear"):
        warp.birds_eye_homography([[0, 0], [1, 1], [2, 2], [0, 1]], square, 10.0)
    with pytest.raises(ValueError, match="four points"):
        warp.birds_eye_homography(square + [[2, 2]], square + [[2, 2]], 10.0)
    with pytest.raises(ValueError, match="pixels_per_unit"):
        warp.birds_eye_homography(square, square, -1.0)
