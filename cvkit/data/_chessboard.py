"""Synthetic chessboard views for camera calibration (Chapter 8), with their ground truth.

A planar chessboard printed on a sheet of paper is "photographed" by a known camera — intrinsic
matrix A, lens distortion (k, p) and a pose (R, t) per view — and rendered the way a sensor
records it: every pixel gets the *area average* of the scene over its square (anti-aliasing
by supersampling the pixels that straddle an edge, 8×8 samples by default), then Gaussian
sensor noise is added. Because the scene is known exactly, so are the image positions of the
inner corners: they are returned with the images and are what corner detectors and
calibration routines are measured against.

Conventions (those of :mod:`cvkit.camera` and of the catalog):

- the board's world frame has its origin at the first inner corner, x along the rows of the
  board (``cols`` inner corners), y along its columns (``rows`` inner corners) and z = 0 on
  the board, pointing away from the camera for every generated pose; the inner corners are
  ``(c·s, r·s, 0)`` in the order ``r·cols + c`` (OpenCV's, and
  :func:`cvkit.calibration.chessboard_points`'s);
- the board has ``(cols + 1) × (rows + 1)`` squares; the square whose corner is the origin
  and lies at x, y < 0 is dark; around the squares the paper leaves a light margin of
  ``margin`` squares, beyond it the background is uniform;
- pixel ``[row, col]`` is the unit square centred on ``(x, y) = (col, row)``.

>>> views = chessboard_views(n_views=2, render=False)
>>> views.image_points.shape, views.world_points.shape
((2, 54, 2), (54, 3))
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import AttributeDict, as_rng, check_allocation, check_int, check_real, check_size

__all__ = ["ChessboardViews", "render_chessboard", "random_board_poses", "chessboard_views"]

#: default camera of the chapter: fu = 800, fv = 820, principal point (320, 240), 640×480
DEFAULT_A = ((800.0, 0.0, 320.0), (0.0, 820.0, 240.0), (0.0, 0.0, 1.0))
#: the most samples per pixel side :func:`render_chessboard` takes (1/4096 of a grey step)
MAX_SUPERSAMPLE = 64
#: the most rejection-sampling attempts :func:`random_board_poses` makes (about 10 s)
MAX_TRIES = 100_000


class ChessboardViews(AttributeDict):
    """The rendered views and their ground truth: a dict whose keys are also attributes.

    Keys: ``images`` (list of images, or None when not rendered), ``world_points``
    ``(cols·rows, 3)``, ``image_points`` ``(n_views, cols·rows, 2)`` (exact distorted
    projections of the inner corners, before noise), ``A``, ``k`` (k1, k2, k3), ``p``
    (p1, p2), ``rotations`` ``(n_views, 3, 3)``, ``translations`` ``(n_views, 3)``, ``cols``,
    ``rows``, ``square_size``, ``image_size`` (rows, cols) and ``noise``.
    """


# --------------------------------------------------------------------------------------------
# argument checks
# --------------------------------------------------------------------------------------------
def _camera(A: ArrayLike) -> np.ndarray:
    from ..camera import as_intrinsics

    A = as_intrinsics(A, "A")
    return A / A[2, 2]


def _pose(R: ArrayLike, t: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    from ..camera import as_rotation, as_translation

    return as_rotation(R, "R"), as_translation(t, "t")


def _image_size(image_size: object) -> tuple[int, int]:
    """``(rows, cols)`` >= 2, with the rays of every pixel corner (three float64 each) in 2 GiB."""
    if not isinstance(image_size, (tuple, list)) or len(image_size) != 2:
        raise ValueError(f"image_size must be a pair (rows, cols), got {image_size!r}")
    rows = check_int(image_size[0], "image_size[0] (rows)", minimum=2)
    cols = check_int(image_size[1], "image_size[1] (cols)", minimum=2)
    check_allocation((rows + 1, cols + 1, 3), "image_size", what="the rays of the pixel corners")
    return rows, cols


def _board(cols: int, rows: int, square_size: float, margin: float) -> tuple[int, int, float, float]:
    cols = check_int(cols, "cols", minimum=2)
    rows = check_int(rows, "rows", minimum=2)
    square_size = check_real(square_size, "square_size", positive=True)
    margin = check_real(margin, "margin", nonnegative=True)
    return cols, rows, square_size, margin


def _distortion(k: ArrayLike, p: ArrayLike) -> tuple[tuple[float, ...], tuple[float, ...]]:
    from ..camera import distortion_coefficients

    kk, pp = distortion_coefficients(k, p)
    return tuple(float(v) for v in kk), tuple(float(v) for v in pp)


# --------------------------------------------------------------------------------------------
# rendering
# --------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=8)
def _rays(A_key: tuple[float, ...], k: tuple[float, ...], p: tuple[float, ...], rows: int, cols: int) -> np.ndarray:
    """Ideal normalised coordinates (x, y) of the pixel *corners*: shape (rows + 1, cols + 1, 2).

    The distortion is inverted by Newton's method on the 2×2 system (converges in a few
    steps wherever the distortion is invertible); the result is cached per camera.
    """
    A = np.array(A_key).reshape(3, 3)
    u = np.arange(cols + 1) - 0.5
    v = np.arange(rows + 1) - 0.5
    uu, vv = np.meshgrid(u, v)
    yd = (vv - A[1, 2]) / A[1, 1]
    xd = (uu - A[0, 2] - A[0, 1] * yd) / A[0, 0]
    k1, k2, k3 = k
    p1, p2 = p
    # Newton's step is element-wise, so a point it leaves exactly unchanged stays so: once
    # most points have settled, only the others are stepped again (the same numbers as
    # stepping all of them twelve times)
    x_all, y_all = xd.ravel().copy(), yd.ravel().copy()
    x, y, xt, yt = x_all, y_all, xd.ravel(), yd.ravel()
    moving: np.ndarray | None = None                        # None: every point
    for _ in range(12):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)          # d radial / d r²
        xx2, yy2 = 2 * x * x, 2 * y * y
        fx = x * radial + 2 * p1 * x * y + p2 * (r2 + xx2) - xt
        fy = y * radial + p1 * (r2 + yy2) + 2 * p2 * x * y - yt
        jxx = radial + xx2 * dradial + 2 * p1 * y + 6 * p2 * x
        jxy = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y  # = d fx / dy = d fy / dx
        jyy = radial + yy2 * dradial + 6 * p1 * y + 2 * p2 * x
        det = jxx * jyy - jxy * jxy
        with np.errstate(divide="ignore", invalid="ignore"):
            x_next = x - (jyy * fx - jxy * fy) / det
            y_next = y - (jxx * fy - jxy * fx) / det
        # unchanged means the same bits (-0.0 and 0.0 differ; a NaN stays a NaN either way)
        changed = (x_next.view(np.int64) != x.view(np.int64)) | (y_next.view(np.int64) != y.view(np.int64))
        if moving is None:
            x_all, y_all = x_next, y_next
            if 4 * np.count_nonzero(changed) > changed.size:
                x, y = x_all, y_all
                continue
            moving = np.flatnonzero(changed)
        else:
            x_all[moving], y_all[moving] = x_next, y_next
            moving = moving[changed]
        if not moving.size:
            break
        x, y, xt, yt = x_all[moving], y_all[moving], xd.ravel()[moving], yd.ravel()[moving]
    x, y = x_all.reshape(xd.shape), y_all.reshape(xd.shape)
    out = np.stack([x, y], axis=-1)
    out.setflags(write=False)
    return out


def _level(value: ArrayLike | None, name: str, color: bool, grey: float, rgb: tuple[float, float, float]) -> np.ndarray:
    """One intensity: ``(3,)`` for colour (a grey level is repeated), ``(1,)`` otherwise."""
    if value is None:
        return np.array(rgb) if color else np.array([grey])
    what = "a grey level or an RGB triple" if color else "a grey level"
    try:
        level = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be {what} or None, got {value!r}") from None
    if not np.all(np.isfinite(level)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if not color:
        if level.size != 1:
            raise ValueError(f"{name} must be {what} or None, got shape {level.shape}")
        return np.array([float(level.reshape(-1)[0])])
    try:
        return np.broadcast_to(level, (3,))
    except ValueError:
        raise ValueError(f"{name} must be {what} or None, got shape {level.shape}") from None


def _levels(color: bool, dark: ArrayLike | None, light: ArrayLike | None,
            background: ArrayLike | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (_level(dark, "dark", color, 0.1, (0.10, 0.10, 0.13)),
            _level(light, "light", color, 0.9, (0.93, 0.91, 0.86)),
            _level(background, "background", color, 0.45, (0.30, 0.42, 0.55)))


def _plane_homography(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """G = [r1 r2 t]⁻¹: maps a ray (x, y, 1) of the camera to homogeneous board coordinates
    (x_W, y_W, 1)·w, with w = 1/z_C (> 0 for points of the plane in front of the camera)."""
    M = np.column_stack([R[:, 0], R[:, 1], t])
    return np.linalg.inv(M)


def _board_xy(X: np.ndarray, Y: np.ndarray, Wh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Euclidean board coordinates from homogeneous ones; +inf where the plane is behind."""
    behind = ~(Wh > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        xw = X / Wh
        yw = Y / Wh
    np.copyto(xw, np.inf, where=behind)
    np.copyto(yw, np.inf, where=behind)
    return xw, yw


def _labels(xw: np.ndarray, yw: np.ndarray, cols: int, rows: int, s: float, margin: float) -> np.ndarray:
    """0 dark square, 1 light square or paper margin, 2 background (int8)."""
    with np.errstate(invalid="ignore"):
        u = xw / s
        v = yw / s
        on_paper = (u >= -1 - margin) & (u <= cols + margin) & (v >= -1 - margin) & (v <= rows + margin)
        on_squares = (u >= -1) & (u < cols) & (v >= -1) & (v < rows)
        # the parity only matters on the squares, where u and v are finite
        parity = (np.floor(u) + np.floor(v)) % 2
    dark = on_squares & (parity == 0)   # square (-1, -1), at the origin, is dark
    labels = np.where(on_paper, np.int8(1), np.int8(2))
    labels[dark] = 0
    return labels


def render_chessboard(A: ArrayLike, R: ArrayLike, t: ArrayLike, cols: int = 9, rows: int = 6,
                      square_size: float = 25.0, image_size: tuple[int, int] = (480, 640),
                      k: ArrayLike = (0.0, 0.0, 0.0), p: ArrayLike = (0.0, 0.0), noise: float = 0.0,
                      rng: np.random.Generator | int | None = None, margin: float = 0.6, supersample: int = 8,
                      color: bool = False, dark: ArrayLike | None = None, light: ArrayLike | None = None,
                      background: ArrayLike | None = None) -> np.ndarray:
    """Render one view of a chessboard through a camera with lens distortion.

    Parameters
    ----------
    A : (3, 3) array_like
        Intrinsic matrix (upper triangular).
    R, t : (3, 3) and (3,) array_like
        Pose of the board: world (board) → camera, ``M_C = R·M_W + t``.
    cols, rows : int
        Inner corners per row and per column of the board (≥ 2): ``cols + 1`` by ``rows + 1``
        squares.
    square_size : float
        Side of a square in world units (> 0).
    image_size : (rows, cols)
        Size of the image in pixels, each >= 2; the rays of the ``(rows + 1)(cols + 1)``
        pixel corners may take at most 2 GiB (``ValueError`` naming ``image_size``).
    k, p : sequences
        Radial ``(k1[, k2[, k3]])`` and tangential ``(p1, p2)`` distortion (OpenCV's model,
        :func:`cvkit.camera.distort`).
    noise : float
        Standard deviation of the additive Gaussian sensor noise (image in [0, 1]); the result
        is clipped to [0, 1].
    rng : numpy.random.Generator, int or None
        Source of the noise.
    margin : float
        Width of the light paper border around the squares, in squares.
    supersample : int
        Samples per side of a pixel that straddles an edge (the area average is taken over
        ``supersample²`` points), 1..64 (:data:`MAX_SUPERSAMPLE`; 64 already resolves 1/4096
        of the contrast); pixels entirely inside one region are not sampled.
    color : bool
        Return an RGB image ``(H, W, 3)`` (a bluish background, slightly warm paper).
    dark, light, background : float or RGB triple, optional
        Intensities of the dark squares, of the light squares and paper, and of the background
        (defaults 0.1, 0.9, 0.45 in grey).

    Returns
    -------
    (H, W) or (H, W, 3) float64 ndarray in [0, 1]

    Notes
    -----
    Every pixel corner is traced back through the camera: pixel → A⁻¹ → undistorted by
    Newton's method (cached per camera) → ray → intersection with the board plane z_W = 0. A
    pixel whose four corners (or whose neighbours' corners) do not all see the same region
    straddles an edge and is supersampled (its sample rays interpolated between its corners,
    then intersected with the plane exactly). The ideal image is then the exact area average
    up to ``1/supersample²`` quantisation: the inner corners of the rendering sit where
    ``camera.project_full`` puts them, to about 1e-3 px.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[200.0, 0, 60], [0, 200, 45], [0, 0, 1]])
    >>> img = render_chessboard(A, np.eye(3), [-25.0, -15.0, 250.0], cols=4, rows=3, square_size=10.0,
    ...                         image_size=(90, 120))
    >>> img.shape, float(img.min()) >= 0.1 - 1e-12, float(img.max()) <= 0.9 + 1e-12
    ((90, 120), True, True)
    """
    A = _camera(A)
    R, t = _pose(R, t)
    cols, rows, s, margin = _board(cols, rows, square_size, margin)
    H, W = _image_size(image_size)
    kk, pp = _distortion(k, p)
    noise = check_real(noise, "noise", nonnegative=True)
    ss = check_size(supersample, "supersample", maximum=MAX_SUPERSAMPLE)
    levels = _levels(bool(color), dark, light, background)
    values = np.stack(levels)                              # (3 labels, channels)

    rays = _rays(tuple(A.ravel().tolist()), kk, pp, H, W)  # (H+1, W+1, 2)
    G = _plane_homography(R, t)
    homog = rays @ G[:, :2].T + G[:, 2]                    # (H+1, W+1, 3) linear in the ray
    xw, yw = _board_xy(homog[..., 0], homog[..., 1], homog[..., 2])
    corner_labels = _labels(xw, yw, cols, rows, s, margin)  # (H+1, W+1)
    c00, c01 = corner_labels[:-1, :-1], corner_labels[:-1, 1:]
    c10, c11 = corner_labels[1:, :-1], corner_labels[1:, 1:]
    mixed = (c00 != c01) | (c00 != c10) | (c00 != c11)
    grown = mixed.copy()                                   # a junction can hide inside a pixel
    grown[1:, :] |= mixed[:-1, :]
    grown[:-1, :] |= mixed[1:, :]
    grown[:, 1:] |= mixed[:, :-1]
    grown[:, :-1] |= mixed[:, 1:]
    image = values[c00]                                    # (H, W, channels)
    r_idx, c_idx = np.nonzero(grown)
    if r_idx.size:
        offsets = (np.arange(ss) + 0.5) / ss                # fractions inside the pixel
        grid_y, grid_x = np.meshgrid(offsets, offsets, indexing="ij")
        fx, fy = grid_x.ravel(), grid_y.ravel()              # (ss²,)
        fxy = fx * fy
        chunk = max(1, 250_000 // (ss * ss))
        for start in range(0, r_idx.size, chunk):
            r = r_idx[start:start + chunk]
            c = c_idx[start:start + chunk]
            h00, h01, h10, h11 = homog[r, c], homog[r, c + 1], homog[r + 1, c], homog[r + 1, c + 1]
            # bilinear interpolation of the (homogeneous) board coordinates inside the pixel:
            # exact for the rays up to the curvature of the lens over one pixel
            a0, ax, ay, axy = h00, h01 - h00, h10 - h00, h11 - h01 - h10 + h00
            X = a0[:, 0:1] + ax[:, 0:1] * fx + ay[:, 0:1] * fy + axy[:, 0:1] * fxy
            Y = a0[:, 1:2] + ax[:, 1:2] * fx + ay[:, 1:2] * fy + axy[:, 1:2] * fxy
            Wh = a0[:, 2:3] + ax[:, 2:3] * fx + ay[:, 2:3] * fy + axy[:, 2:3] * fxy
            sx, sy = _board_xy(X, Y, Wh)
            labels = _labels(sx, sy, cols, rows, s, margin)                     # (n, ss²)
            # the share of each label among the pixel's samples (n, 3)
            counts = np.bincount((labels + 3 * np.arange(len(r))[:, None]).ravel(), minlength=3 * len(r))
            counts = counts.reshape(len(r), 3) / labels.shape[1]
            image[r, c] = counts @ values
    if noise > 0:
        image = image + as_rng(rng).normal(0.0, noise, image.shape)
    image = np.clip(image, 0.0, 1.0)
    return image if color else image[..., 0]


# --------------------------------------------------------------------------------------------
# poses and views
# --------------------------------------------------------------------------------------------
def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    from ..camera import rotation_matrix

    return rotation_matrix(roll, pitch, yaw)


def _project(points: np.ndarray, A: np.ndarray, R: np.ndarray, t: np.ndarray, k: tuple[float, ...],
             p: tuple[float, ...]) -> np.ndarray:
    """:func:`cvkit.camera.project_full` without its argument checks (the pose sampler projects
    thousands of candidate poses whose camera, rotation and translation it has made itself, and
    whose ``k`` and ``p`` :func:`_distortion` has checked): the reference's lens, bit for bit
    the same numbers (``tests/library/test_calibration.py``)."""
    from ..camera import project_checked

    return project_checked(points, A, R, t, np.array(k, dtype=np.float64), np.array(p, dtype=np.float64))


class _PoseTries:
    """The tries of :func:`random_board_poses`' rejection sampler, a block at a time.

    A try takes ``m`` uniforms of ``rng`` — the yaw, (whether to flip, when ``flip``), roll,
    pitch, the fill and the board centre's two offsets — and keeps the pose when the board faces
    the camera (``R[2, 2] > 0.2``) and every point of the paper's outline lies in front of the
    camera and ``border`` pixels inside the image. :meth:`exact` makes one try exactly so.
    :meth:`hopeless` rules out, for a whole block of tries at once, those that fail by a clear
    margin (:attr:`MARGIN`, far above rounding), so that only the few others need :meth:`exact`:
    the poses are those of trying one after the other, bit for bit, at a fraction of the cost
    (most tries fail: tens per pose for the chessboard checks' small images).
    """

    MARGIN = 1e-6

    def __init__(self, A, H, W, outline, centre, board_width, diagonal, spin, tilt, lo, hi, border, flip, kk, pp):
        self.A, self.H, self.W, self.outline, self.centre = A, H, W, outline, centre
        self.board_width, self.diagonal = board_width, diagonal
        self.spin, self.tilt, self.lo, self.hi, self.border, self.flip = spin, tilt, lo, hi, border, flip
        self.kk, self.pp = kk, pp
        self.m = 7 if flip else 6

    def _draws(self, u: np.ndarray):
        """yaw, roll, pitch, fill and the offsets (x, y) from the uniforms, as ``rng.uniform``
        makes them (``low + (high - low) · u``)."""
        spin, tilt, f = self.spin, self.tilt, 2 if self.flip else 1
        yaw = -spin + (spin - -spin) * u[..., 0] + np.where(self.flip & (u[..., 1] < 0.5), np.pi, 0.0)
        roll = -tilt + (tilt - -tilt) * u[..., f]
        pitch = -tilt + (tilt - -tilt) * u[..., f + 1]
        fill = self.lo + (self.hi - self.lo) * u[..., f + 2]
        return yaw, roll, pitch, fill, -0.25 + 0.5 * u[..., f + 3], -0.25 + 0.5 * u[..., f + 4]

    def _pose(self, R, fill, ox, oy, shrink):
        A, W, H = self.A, self.W, self.H
        depth = A[0, 0] * self.board_width / (self.diagonal * fill * shrink)
        target = np.stack([ox * W / A[0, 0], oy * H / A[1, 1], np.ones_like(ox)], axis=-1) * np.expand_dims(depth, -1)
        return target - R @ self.centre

    def exact(self, u: np.ndarray, number: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Try ``number`` (counted from 1) on its uniforms ``u``: ``(R, t)`` if kept, else None."""
        yaw, roll, pitch, fill, ox, oy = (float(v) for v in self._draws(u))
        R = _rotation(roll, pitch, yaw)
        shrink = 0.97 ** (number // 50)           # when the board keeps sticking out, try smaller
        t = self._pose(R, fill, ox, oy, shrink)
        if R[2, 2] <= 0.2:                        # seen too edge-on (or from behind)
            return None
        corners = _project(self.outline, self.A, R, t, self.kk, self.pp)
        z = (self.outline @ R.T + t)[:, 2]
        lo, right, bottom = self.border - 0.5, self.W - 0.5 - self.border, self.H - 0.5 - self.border
        if np.all(z > 0) and np.all(corners[:, 0] >= lo) and np.all(corners[:, 0] <= right) \
                and np.all(corners[:, 1] >= lo) and np.all(corners[:, 1] <= bottom):
            return R, t
        return None

    def hopeless(self, u: np.ndarray, done: int) -> np.ndarray:
        """``(K,)`` bool: the tries ``done + 1 ..`` on the rows of ``u`` that :meth:`exact` would
        certainly reject (by more than :attr:`MARGIN`); False does not mean kept."""
        from ..camera import rotation_matrices

        yaw, roll, pitch, fill, ox, oy = self._draws(u)
        R = rotation_matrices(roll, pitch, yaw)                            # (K, 3, 3)
        shrink = 0.97 ** ((done + 1 + np.arange(len(u))) // 50)
        t = self._pose(R, fill, ox, oy, shrink)                            # (K, 3)
        camera = self.outline @ R.transpose(0, 2, 1) + t[:, None, :]       # (K, points, 3)
        z = camera[..., 2]
        # project_full's last three steps on the points in the camera frame (R = I, t = 0)
        corners = _project(camera.reshape(-1, 3), self.A, np.eye(3), np.zeros(3), self.kk, self.pp)
        x, y = corners[:, 0].reshape(z.shape), corners[:, 1].reshape(z.shape)
        e = self.MARGIN
        with np.errstate(invalid="ignore"):
            ex, ey = e * (1.0 + np.abs(x)), e * (1.0 + np.abs(y))  # relative: rounding grows with size
            outside = (x < self.border - 0.5 - ex) | (x > self.W - 0.5 - self.border + ex) \
                | (y < self.border - 0.5 - ey) | (y > self.H - 0.5 - self.border + ey)
        behind = z < -e * np.abs(camera).max(axis=(1, 2))[:, None]
        return (R[:, 2, 2] < 0.2 - e) | behind.any(axis=1) | outside.any(axis=1)


def random_board_poses(n: int, A: ArrayLike, image_size: tuple[int, int] = (480, 640), cols: int = 9,
                       rows: int = 6, square_size: float = 25.0, k: ArrayLike = (0.0, 0.0, 0.0),
                       p: ArrayLike = (0.0, 0.0), rng: np.random.Generator | int | None = None, tilt: float = 0.7,
                       spin: float = 0.35, fill: tuple[float, float] = (0.55, 0.95), margin: float = 0.6,
                       border: float = 8.0, flip: bool = False,
                       max_tries: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """Random poses of a chessboard that keep the whole sheet of paper inside the image.

    Parameters
    ----------
    n : int
        Number of poses, 0 <= n <= ``max_tries`` (each pose takes at least one try).
    A, image_size, cols, rows, square_size, k, p, margin :
        Camera and board, as for :func:`render_chessboard`.
    rng : numpy.random.Generator, int or None
    tilt : float
        Largest tilt of the board about its x and y axes (radians, uniform in ±tilt).
    spin : float
        Largest rotation about the board's normal (radians, uniform in ±spin).
    fill : (float, float)
        Range of the apparent diagonal of the paper as a fraction of the image diagonal (before
        perspective), both > 0; sets the distance. Reduced gradually when poses keep failing.
    border : float
        Minimal distance in pixels between the projected paper corners and the image border.
    flip : bool
        Also turn half of the boards by π about their normal (upside down).
    max_tries : int
        Rejection-sampling attempts, for all the poses together, before giving up
        (ValueError); 1 <= max_tries <= 100000 (:data:`MAX_TRIES`, about 10 s).

    Returns
    -------
    rotations : (n, 3, 3) float64 ndarray
    translations : (n, 3) float64 ndarray
        World (board) → camera poses with the board in front of the camera (t_z > 0) and its z
        axis pointing away from the camera.
    """
    A = _camera(A)
    H, W = _image_size(image_size)
    cols, rows, s, margin = _board(cols, rows, square_size, margin)
    max_tries = check_size(max_tries, "max_tries", maximum=MAX_TRIES)
    n = check_size(n, "n", minimum=0, maximum=max_tries)
    lo, hi = _fill(fill)
    tilt = check_real(tilt, "tilt", nonnegative=True)
    spin = check_real(spin, "spin", nonnegative=True)
    border = check_real(border, "border", nonnegative=True)
    rng = as_rng(rng)
    kk, pp = _distortion(k, p)
    paper = np.array([[-s * (1 + margin), -s * (1 + margin), 0.0], [s * (cols + margin), -s * (1 + margin), 0.0],
                      [s * (cols + margin), s * (rows + margin), 0.0], [-s * (1 + margin), s * (rows + margin), 0.0]])
    edge = np.linspace(0, 1, 9)[:, None]
    outline = np.concatenate([paper[i] + edge * (paper[(i + 1) % 4] - paper[i]) for i in range(4)])
    centre = np.array([(cols - 1) * s / 2, (rows - 1) * s / 2, 0.0])
    board_width = float(np.hypot((cols + 1 + 2 * margin) * s, (rows + 1 + 2 * margin) * s))  # the paper
    diagonal = float(np.hypot(H, W))
    tries = _PoseTries(A, H, W, outline, centre, board_width, diagonal, spin, tilt, lo, hi, border, flip, kk, pp)
    rotations: list[np.ndarray] = []
    translations: list[np.ndarray] = []
    done = 0                                      # tries made
    block = 16
    while len(rotations) < n:
        if done == max_tries:
            raise ValueError(
                f"could not place the board inside the image in {max_tries} tries: make the board smaller "
                "(fill), the tilt smaller or the image larger")
        size = min(block, max_tries - done)
        state = rng.bit_generator.state
        uniforms = rng.random((size, tries.m))    # the uniforms of the next `size` tries, in order
        used = size
        for i in np.flatnonzero(~tries.hopeless(uniforms, done)).tolist():
            pose = tries.exact(uniforms[i], done + i + 1)
            if pose is not None:
                rotations.append(pose[0])
                translations.append(pose[1])
                if len(rotations) == n:
                    used = i + 1
                    break
        if used < size:                           # leave rng just after the last try made
            rng.bit_generator.state = state
            rng.random(used * tries.m)
        done += used
        block = min(4 * block, 1024)
    return np.array(rotations).reshape(n, 3, 3), np.array(translations).reshape(n, 3)


def _fill(fill: object) -> tuple[float, float]:
    if not isinstance(fill, (tuple, list, np.ndarray)) or len(fill) != 2:
        raise ValueError(f"fill must be a pair (low, high) of fractions, got {fill!r}")
    return check_real(fill[0], "fill[0]", positive=True), check_real(fill[1], "fill[1]", positive=True)


def chessboard_views(n_views: int = 15, cols: int = 9, rows: int = 6, square_size: float = 25.0,
                     image_size: tuple[int, int] = (480, 640), A: ArrayLike | None = None,
                     k: ArrayLike = (-0.2, 0.05), p: ArrayLike = (0.0, 0.0), noise: float = 0.01,
                     rng: np.random.Generator | int | None = 0, render: bool = True,
                     **pose_options: Any) -> ChessboardViews:
    """Views of a chessboard through a known camera: images and their ground truth.

    Parameters
    ----------
    n_views : int
        Number of views (random poses, :func:`random_board_poses`), at most its ``max_tries``
        (2000 by default); the rendered images together, and the corner positions of all
        views, may take at most 2 GiB (``ValueError`` naming ``n_views``, ``cols`` or ``rows``).
    cols, rows, square_size :
        The board: 9 × 6 inner corners of 25 mm by default.
    image_size : (rows, cols)
        Image size, 480 × 640 by default.
    A : (3, 3) array_like, optional
        Intrinsic matrix; default fu = 800, fv = 820, u0 = 320, v0 = 240.
    k, p : sequences
        Lens distortion; default k1 = −0.2, k2 = 0.05 (barrel), no tangential terms.
    noise : float
        Standard deviation of the sensor noise of the rendered images (intensities in [0, 1]).
    rng : numpy.random.Generator, int or None
        Seed of the poses and the noise (0 by default: the same views every time).
    render : bool
        Render the images (False: only the geometry, much faster).
    **pose_options
        Passed on to :func:`random_board_poses` (``tilt``, ``spin``, ``fill``, ``flip``, ...).

    Returns
    -------
    ChessboardViews
        A dict with attribute access: ``images``, ``world_points``, ``image_points`` (exact
        corner positions, distorted, in the order of the world points), ``A``, ``k`` (3
        values), ``p``, ``rotations``, ``translations``, ``cols``, ``rows``, ``square_size``,
        ``image_size``, ``noise``.

    Examples
    --------
    >>> views = chessboard_views(n_views=1, image_size=(240, 320), A=[[400, 0, 160], [0, 410, 120], [0, 0, 1]])
    >>> views.images[0].shape, views.image_points.shape
    ((240, 320), (1, 54, 2))
    """
    rng = as_rng(rng)
    n_views = check_int(n_views, "n_views", minimum=1)
    A = _camera(np.array(DEFAULT_A) if A is None else A)
    H, W = _image_size(image_size)
    cols, rows, s, margin = _board(cols, rows, square_size, pose_options.get("margin", 0.6))
    max_tries = pose_options.get("max_tries", 2000)
    if isinstance(max_tries, int) and n_views > max_tries:
        raise ValueError(f"n_views must be <= max_tries ({max_tries}: each view takes at least one try), got {n_views}")
    corners = "cols" if cols >= rows else "rows"
    check_allocation((n_views, cols * rows, 2), corners if cols * rows > n_views else "n_views",
                     what=f"the image points of n_views={n_views} views of cols × rows = {cols}×{rows} corners")
    if render:
        check_allocation((n_views, H, W), "n_views", what=f"n_views={n_views} rendered images")
    kk, pp = _distortion(k, p)
    rotations, translations = random_board_poses(n_views, A, (H, W), cols, rows, s, kk, pp, rng=rng, **pose_options)
    jj, ii = np.mgrid[0:rows, 0:cols]
    world = np.column_stack([ii.ravel() * s, jj.ravel() * s, np.zeros(cols * rows)])
    points = np.stack([_project(world, A, R, t, kk, pp) for R, t in zip(rotations, translations)])
    images = None
    if render:
        images = [render_chessboard(A, R, t, cols, rows, s, (H, W), kk, pp, noise=noise, rng=rng, margin=margin)
                  for R, t in zip(rotations, translations)]
    return ChessboardViews(images=images, world_points=world, image_points=points, A=A, k=np.array(kk),
                           p=np.array(pp), rotations=rotations, translations=translations, cols=cols, rows=rows,
                           square_size=s, image_size=(H, W), noise=float(noise))
