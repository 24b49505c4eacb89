"""Synthetic scenes for object detection (Chapter 6): an industrial "part" of known shape
placed at a known pose (translation, scale, rotation) among clutter, with inverted contrast
polarity, partial occlusion and noise, and images of line segments for the Hough transform.

Everything is made by code and anti-aliased by supersampling (a boundary pixel gets the
fraction of its area inside the shape). Coordinates follow the catalog: pixel ``[row, col]``
is centred on ``(x, y) = (col, row)``; angles are radians with y pointing down the rows (a
positive angle turns clockwise on screen).

>>> tpl, outline = part_template(32)
>>> tpl.shape, outline.shape[1], float(tpl.min()), float(tpl.max())
((32, 32), 2, 0.2, 0.8)
>>> img, pose = part_scene((64, 80), centre=(40.0, 30.0), size=32, clutter=0, noise=0.0, rng=0)
>>> img.shape, pose["centre"], to_scene(pose, pose["template_centre"])
((64, 80), (40.0, 30.0), (40.0, 30.0))
"""
from __future__ import annotations

import math
from typing import Any, Literal, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_rng, check_int, check_real, check_size
from ._common import Inside, as_points, centre_point, check_drawing, coverage, image_shape, samples

__all__ = ["polygon_image", "part_outline", "part_template", "part_scene", "to_scene", "segments_image"]

POLARITIES = ("normal", "inverted", "mixed")
#: the most clutter shapes :func:`part_scene` draws
MAX_CLUTTER = 1000


def _inside_polygon(vertices: np.ndarray) -> Inside:
    """Even-odd rule, vectorised over the sample grid (a loop over the polygon's edges).

    On the sample grid of :func:`~cvkit.data._common.samples` (``y`` an ascending column, ``x``
    a row) an edge is evaluated on the rows its vertical extent crosses only: the same values,
    in a fraction of the time for a polygon much smaller than the image (the clutter of
    :func:`part_scene`)."""
    def inside(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        hit = np.zeros(np.broadcast(x, y).shape, dtype=bool)
        column = y[:, 0] if y.ndim == 2 and y.shape[1] == 1 and x.ndim == 2 and x.shape[0] == 1 else None
        if column is not None and np.any(column[1:] < column[:-1]):
            column = None
        n = len(vertices)
        for k in range(n):
            x0, y0 = vertices[k]
            x1, y1 = vertices[(k + 1) % n]
            if y0 == y1:
                continue
            if column is None:
                crosses = (y0 > y) != (y1 > y)
                x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
                hit ^= crosses & (x < x_at)
                continue
            # (y0 > y) != (y1 > y) holds exactly for min(y0, y1) <= y < max(y0, y1)
            lo, hi = np.searchsorted(column, (min(y0, y1), max(y0, y1)), side="left")
            if hi > lo:
                rows = y[lo:hi]
                hit[lo:hi] ^= x < x0 + (rows - y0) * (x1 - x0) / (y1 - y0)
        return hit
    return inside


def _vertices(vertices: ArrayLike) -> np.ndarray:
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.all(np.isfinite(v)):
        raise ValueError(f"vertices must be an (N, 2) array of finite (x, y) with N >= 3, got shape {v.shape}")
    return v


def polygon_image(shape: tuple[int, int], vertices: ArrayLike, inside: float = 1.0, outside: float = 0.0,
                  supersample: int = 4) -> np.ndarray:
    """A filled polygon (even-odd rule), anti-aliased.

    Parameters
    ----------
    shape : (rows, cols)
    vertices : (N, 2) array_like
        Corners ``(x, y)`` in order, N ≥ 3 (the polygon closes itself).
    inside, outside : float
        Levels of the polygon and of the background.
    supersample : int
        Samples per pixel along each axis.

    The image and its grid of ``supersample²`` samples per pixel may each take at most
    2 GiB (``ValueError`` naming ``shape`` or ``supersample``), and the drawing, about ten
    operations per sample and vertex, at most 2**36 (naming ``vertices``).

    Returns
    -------
    (rows, cols) float64 ndarray

    >>> polygon_image((4, 5), [(0, 0), (3, 0), (3, 2), (0, 2)], supersample=2)
    array([[0.25, 0.5 , 0.5 , 0.25, 0.  ],
           [0.5 , 1.  , 1.  , 0.5 , 0.  ],
           [0.25, 0.5 , 0.5 , 0.25, 0.  ],
           [0.  , 0.  , 0.  , 0.  , 0.  ]])
    """
    rows, cols = image_shape(shape)
    v = _vertices(vertices)
    inside = check_real(inside, "inside")
    outside = check_real(outside, "outside")
    check_drawing(rows, cols, supersample, len(v), "vertices", f"a polygon of {len(v)} vertices")
    cov = coverage(rows, cols, _inside_polygon(v), supersample)
    return outside + (inside - outside) * cov


def part_outline(size: float = 40.0) -> np.ndarray:
    """Corners ``(x, y)`` of the "part": a bracket with a rounded head, a notch and a slanted
    side, no symmetry, centred on the origin and ``size`` wide (``0.75·size`` tall).

    >>> v = part_outline(40.0)
    >>> v.shape, float(np.ptp(v[:, 0])), float(np.ptp(v[:, 1]))
    ((21, 2), 40.0, 30.0)
    """
    size = check_real(size, "size", positive=True)
    body = [(-0.5, 0.4), (-0.5, -0.05), (-0.3, -0.3), (-0.05, -0.3), (-0.05, -0.12),
            (0.05, -0.12), (0.05, -0.3)]
    # a half-disc head on the right, radius 0.3 about (0.2, -0.05), from the top round to the bottom
    head = [(0.2 + 0.3 * math.sin(t), -0.05 - 0.3 * math.cos(t)) for t in np.linspace(0.0, math.pi, 9)]
    tail = [(0.2, 0.4), (0.1, 0.4), (0.1, 0.15), (-0.2, 0.15), (-0.3, 0.4), (-0.5, 0.4)]
    v = np.array(body + head[:] + tail[:-1], dtype=np.float64)
    v[:, 0] -= (v[:, 0].max() + v[:, 0].min()) / 2
    v[:, 1] -= (v[:, 1].max() + v[:, 1].min()) / 2
    return v * (size / np.ptp(v[:, 0]))


def part_template(size: int = 40, inside: float = 0.8, outside: float = 0.2, margin: int = 4,
                  supersample: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """The model image: the part, ``size − 2·margin`` wide, centred in a ``size × size`` square.

    ``size`` >= 8 and ``supersample`` are bounded as the ``shape`` and ``supersample`` of
    :func:`polygon_image` (``ValueError`` naming them).

    Returns
    -------
    template : (size, size) float64 ndarray
    outline : (N, 2) float64 ndarray
        The part's corners ``(x, y)`` in template pixels.
    """
    size = check_int(size, "size", minimum=8)
    margin = check_int(margin, "margin", minimum=0)
    if 2 * margin >= size - 4:
        raise ValueError(f"margin must leave room for the part: size={size}, margin={margin}")
    image_shape((size, size), "size")
    outline = part_outline(size - 2 * margin) + (size - 1) / 2.0
    return polygon_image((size, size), outline, inside, outside, supersample), outline


def to_scene(pose: dict[str, Any], point: Sequence[float]) -> tuple[float, float]:
    """Where the template point ``(x, y)`` lands in the scene of ``pose`` (from :func:`part_scene`):
    ``centre + scale·R(angle)·(point − template_centre)``."""
    cx, cy = pose["centre"]
    tx, ty = pose["template_centre"]
    s, a = pose["scale"], pose["angle"]
    dx, dy = float(point[0]) - tx, float(point[1]) - ty
    return (cx + s * (math.cos(a) * dx - math.sin(a) * dy), cy + s * (math.sin(a) * dx + math.cos(a) * dy))


def _random_clutter(rng: np.random.Generator, rows: int, cols: int, keep_out: tuple[float, float, float],
                    count: int) -> list[tuple[np.ndarray, float]]:
    """Random disks, rotated rectangles and triangles outside the disk ``keep_out``."""
    shapes: list[tuple[np.ndarray, float]] = []
    cx, cy, radius = keep_out
    tries = 0
    while len(shapes) < count and tries < 200 * max(1, count):
        tries += 1
        size = rng.uniform(0.06, 0.16) * min(rows, cols)
        x, y = rng.uniform(0, cols - 1), rng.uniform(0, rows - 1)
        if math.hypot(x - cx, y - cy) < radius + size:
            continue
        kind = rng.integers(3)
        if kind == 0:
            t = np.linspace(0, 2 * math.pi, 24, endpoint=False)
            v = np.stack([x + size * np.cos(t), y + size * np.sin(t)], axis=1)
        elif kind == 1:
            a = rng.uniform(0, math.pi)
            w, h = size, size * rng.uniform(0.3, 1.0)
            corners = np.array([(-w, -h), (w, -h), (w, h), (-w, h)])
            rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
            v = corners @ rot.T + (x, y)
        else:
            t = rng.uniform(0, 2 * math.pi) + np.array([0.0, 2.1, 4.0])
            v = np.stack([x + size * np.cos(t), y + size * np.sin(t)], axis=1)
        shapes.append((v, float(rng.uniform(0.0, 1.0))))
    return shapes


def part_scene(shape: tuple[int, int] = (128, 128), centre: tuple[float, float] | None = None, scale: float = 1.0,
               angle: float = 0.0, size: int = 40, clutter: int = 6, occlusion: float = 0.0, noise: float = 0.02,
               polarity: Literal["normal", "inverted", "mixed"] = "normal",
               rng: np.random.Generator | int | None = None, supersample: int = 4,
               margin: int = 4) -> tuple[np.ndarray, dict[str, Any]]:
    """A scene with the part of :func:`part_template` at a known pose.

    Parameters
    ----------
    shape : (rows, cols)
    centre : (x, y) or None
        Where the template's centre lands; ``None``: drawn at random, the part inside.
    scale, angle : float
        The part is the template's scaled by ``scale`` and turned by ``angle`` (radians, y down).
    size, margin : int
        Size and margin of the template the pose refers to (as :func:`part_template`).
    clutter : int
        Number of random shapes (disks, rectangles, triangles) of random grey levels around,
        not overlapping the part; 0 <= clutter <= 1000 (:data:`MAX_CLUTTER`), and drawing
        them, about 240 operations per sample each, at most 2**36 (``ValueError`` naming
        ``clutter``).
    occlusion : float
        Fraction (0 ≤ f < 1) of the part's outline hidden behind a flat occluder (a half-plane
        in a random direction, clipped to a disk around the part).
    noise : float
        Standard deviation of added Gaussian noise.
    polarity : {"normal", "inverted", "mixed"}
        ``normal``: bright part (0.8) on a dark background (0.2), as the template;
        ``inverted``: dark part on a bright background; ``mixed``: a grey part (0.5) on a
        background that is dark on one side of a line through the part and bright on the other
        (contrast polarity inverted along part of the outline).
    rng : Generator, int or None
    supersample : int
        Samples per pixel along each axis; ``shape`` and ``supersample`` are bounded as for
        :func:`polygon_image`.

    Returns
    -------
    image : (rows, cols) float64 ndarray
    pose : dict
        ``centre`` (x, y), ``scale``, ``angle``, ``template_centre`` (x, y) and ``outline``,
        the part's corners in the scene; map template points with :func:`to_scene`.
    """
    rows, cols = image_shape(shape)
    rng = as_rng(rng)
    size = check_int(size, "size", minimum=8)
    scale = check_real(scale, "scale", positive=True)
    angle = check_real(angle, "angle")
    clutter = check_size(clutter, "clutter", minimum=0, maximum=MAX_CLUTTER)
    check_drawing(rows, cols, supersample, 24 * clutter + 40, "clutter", f"{clutter} clutter shapes and the part")
    occlusion = check_real(occlusion, "occlusion", nonnegative=True)
    if occlusion >= 1:
        raise ValueError(f"occlusion must be < 1, got {occlusion}")
    noise = check_real(noise, "noise", nonnegative=True)
    if not isinstance(polarity, str) or polarity not in POLARITIES:
        raise ValueError(f"polarity must be one of {', '.join(map(repr, POLARITIES))}, got {polarity!r}")
    _, outline_t = part_template(size, margin=margin, supersample=1)
    c_t = ((size - 1) / 2.0, (size - 1) / 2.0)
    half = scale * size / 2.0
    if centre is None:
        lo_x, lo_y = half, half
        hi_x, hi_y = cols - 1 - half, rows - 1 - half
        if hi_x < lo_x or hi_y < lo_y:
            raise ValueError(f"the part (scale {scale}, size {size}) does not fit in an image of shape {(rows, cols)}")
        centre = (float(rng.uniform(lo_x, hi_x)), float(rng.uniform(lo_y, hi_y)))
    else:
        centre = centre_point(centre, rows, cols)
    pose: dict[str, Any] = {"centre": centre, "scale": scale, "angle": angle, "template_centre": c_t}
    outline = np.array([to_scene(pose, p) for p in outline_t])
    pose["outline"] = outline

    x, y = samples(rows, cols, supersample)
    s = supersample

    def down(hit: np.ndarray) -> np.ndarray:
        return hit.reshape(rows, s, cols, s).mean(axis=(1, 3))

    if polarity == "mixed":
        split = float(rng.uniform(0, math.pi))
        side = ((x - centre[0]) * math.cos(split) + (y - centre[1]) * math.sin(split)) > 0
        image = 0.15 + 0.7 * down(side)
        part_level = 0.5
    else:
        image = np.full((rows, cols), 0.2 if polarity == "normal" else 0.8)
        part_level = 0.8 if polarity == "normal" else 0.2
    for vertices, level in _random_clutter(rng, rows, cols, (centre[0], centre[1], half * 1.15), clutter):
        cov = down(_inside_polygon(vertices)(x, y))
        image = image * (1 - cov) + level * cov
    cov = down(_inside_polygon(outline)(x, y))
    image = image * (1 - cov) + part_level * cov
    if occlusion > 0:
        # densely sampled outline: hide the fraction `occlusion` of it furthest along a direction
        closed = np.vstack([outline, outline[:1]])
        pieces = [np.linspace(closed[k], closed[k + 1], 20, endpoint=False) for k in range(len(outline))]
        dense = np.vstack(pieces)
        lengths = np.repeat(np.hypot(*np.diff(closed, axis=0).T) / 20, 20)
        u = float(rng.uniform(0, 2 * math.pi))
        proj = (dense[:, 0] - centre[0]) * math.cos(u) + (dense[:, 1] - centre[1]) * math.sin(u)
        order = np.argsort(proj)[::-1]
        hidden = np.cumsum(lengths[order]) <= occlusion * lengths.sum()
        cut = float(proj[order][hidden].min()) if hidden.any() else float(proj.max()) + 1.0
        region = (((x - centre[0]) * math.cos(u) + (y - centre[1]) * math.sin(u)) >= cut) & (
            np.hypot(x - centre[0], y - centre[1]) <= half * 1.1)
        cov = down(region)
        level = float(rng.uniform(0.35, 0.65)) if polarity != "mixed" else float(rng.choice([0.3, 0.7]))
        image = image * (1 - cov) + level * cov
        pose["occluded"] = float(lengths[order][hidden].sum() / lengths.sum())
    if noise > 0:
        image = image + rng.normal(0.0, noise, image.shape)
    return image, pose


def segments_image(shape: tuple[int, int], segments: ArrayLike, width: float = 1.0, inside: float = 1.0,
                   outside: float = 0.0, supersample: int = 4) -> np.ndarray:
    """Straight segments drawn with a given width, anti-aliased.

    Parameters
    ----------
    shape : (rows, cols)
    segments : (N, 4) array_like
        ``(x0, y0, x1, y1)`` of each segment, finite (any array of 4·N values, read row by
        row).
    width : float
        Stroke width in pixels.
    inside, outside : float
        Levels of the strokes and of the background.
    supersample : int
        Samples per pixel along each axis.

    ``shape`` and ``supersample`` are bounded as for :func:`polygon_image`, and drawing the
    segments, about twenty operations per sample each, at most 2**36 operations
    (``ValueError`` naming ``segments``).

    >>> img = segments_image((5, 7), [(1, 2, 5, 2)], width=1.0, supersample=2)
    >>> img[2], float(img[1].max())
    (array([0., 1., 1., 1., 1., 1., 0.]), 0.0)
    """
    rows, cols = image_shape(shape)
    seg = as_points(segments, "segments", 4)
    width = check_real(width, "width", positive=True)
    inside = check_real(inside, "inside")
    outside = check_real(outside, "outside")
    check_drawing(rows, cols, supersample, 2 * len(seg), "segments", f"{len(seg)} segments")

    def inside_fn(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        hit = np.zeros(np.broadcast(x, y).shape, dtype=bool)
        for x0, y0, x1, y1 in seg:
            dx, dy = x1 - x0, y1 - y0
            length2 = dx * dx + dy * dy
            t = np.clip(((x - x0) * dx + (y - y0) * dy) / length2, 0.0, 1.0) if length2 > 0 else 0.0
            hit |= np.hypot(x - (x0 + t * dx), y - (y0 + t * dy)) <= width / 2
        return hit

    cov = coverage(rows, cols, inside_fn, supersample)
    return outside + (inside - outside) * cov
