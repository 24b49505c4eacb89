"""Colour sensors (§2.13): the Bayer colour filter array and bilinear demosaicking.

Pattern names give the colours of the top-left 2×2 block read row by row: ``"RGGB"`` means

====== ====== ======
\\      col 0  col 1
====== ====== ======
row 0  R      G
row 1  G      B
====== ====== ======

and the block repeats over the whole sensor. **OpenCV names the same layouts differently**
(after the second row's second and third pixels): cvkit ``RGGB`` = OpenCV ``Bayer BG``
(``cv2.COLOR_BayerBG2RGB``), ``BGGR`` = ``Bayer RG``, ``GRBG`` = ``Bayer GB``, ``GBRG`` =
``Bayer GR`` (checked against ``cv2.cvtColor`` in the tests).
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, as_image
from ..registry import algorithm

__all__ = ["bayer_mosaic", "demosaic_bilinear", "PATTERNS", "OPENCV_BAYER_NAMES"]

PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
#: cvkit's pattern name → the name in OpenCV's ``COLOR_Bayer<XY>2RGB`` conversion codes
OPENCV_BAYER_NAMES = {"RGGB": "BG", "BGGR": "RG", "GRBG": "GB", "GBRG": "GR"}
_CHANNEL = {"R": 0, "G": 1, "B": 2}
Pattern = Literal["RGGB", "BGGR", "GRBG", "GBRG"]


def _check_pattern(pattern: str) -> str:
    if not isinstance(pattern, str) or pattern not in PATTERNS:
        raise ValueError(f"pattern must be one of {', '.join(map(repr, PATTERNS))}, got {pattern!r}")
    return pattern


def channel_map(pattern: str, height: int, width: int, offset: int = 0) -> np.ndarray:
    """``(height, width)`` int array: the channel (0 R, 1 G, 2 B) each sensor site measures.

    ``offset`` is the position of the array's first row and column on the sensor (the
    colour of site (i, j) is that of (i + offset, j + offset)).
    """
    block = np.array([_CHANNEL[c] for c in pattern]).reshape(2, 2)
    rows = (np.arange(height) + offset) % 2
    cols = (np.arange(width) + offset) % 2
    return block[rows[:, None], cols[None, :]]


@algorithm("formation.bayer_mosaic", section="2.13", check="cvkit.formation.checks:bayer_mosaic")
def bayer_mosaic(rgb: ArrayLike, pattern: Pattern = "RGGB") -> np.ndarray:
    """The raw image a Bayer-filtered sensor records of a colour scene.

    Parameters
    ----------
    rgb : (H, W, 3) array_like
        The scene as an RGB image, any real dtype, finite values.
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
        Colours of the top-left 2×2 block of the filter array, read row by row.

    Returns
    -------
    (H, W) float64 ndarray
        At each pixel the one channel its filter lets through (values not rescaled).

    Notes
    -----
    §2.13: a sensor measures one value per site; the colour filter array in front of it
    chooses which colour. Every 2×2 block holds two green, one red and one blue filter, so
    half the sites see green and a quarter each red and blue.

    Examples
    --------
    >>> rgb = np.zeros((2, 4, 3)); rgb[..., 0] = 1; rgb[..., 1] = 2; rgb[..., 2] = 3
    >>> bayer_mosaic(rgb, "RGGB")
    array([[1., 2., 1., 2.],
           [2., 3., 2., 3.]])
    >>> bayer_mosaic(rgb, "GBRG")
    array([[2., 3., 2., 3.],
           [1., 2., 1., 2.]])
    """
    img = as_image(rgb, "rgb")
    if img.ndim != 3:
        raise ValueError(f"rgb must be an (H, W, 3) colour image, got shape {img.shape}")
    _check_pattern(pattern)
    channels = channel_map(pattern, img.shape[0], img.shape[1])
    return np.take_along_axis(img, channels[:, :, None], axis=2)[:, :, 0]


@algorithm("formation.demosaic_bilinear", section="2.13", check="cvkit.formation.checks:demosaic_bilinear")
def demosaic_bilinear(raw: ArrayLike, pattern: Pattern = "RGGB") -> np.ndarray:
    """Bilinear demosaicking: an RGB image from a Bayer raw image.

    Parameters
    ----------
    raw : (H, W) array_like
        Raw sensor image, H, W >= 2, any real dtype, finite values.
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
        The filter layout the raw image was taken with (see :func:`bayer_mosaic`).

    Returns
    -------
    (H, W, 3) float64 ndarray
        Measured samples are kept exactly; each missing sample is the mean of the nearest
        sites of its colour:

        - green at a red or blue site: its 4 horizontal and vertical neighbours;
        - red (blue) at a green site: the 2 neighbours in the row or the column that holds
          red (blue);
        - red at a blue site and blue at a red site: the 4 diagonal neighbours.

    Raises
    ------
    ValueError
        ``raw`` not 2-D with H, W >= 2 or not finite, unknown ``pattern``.

    Notes
    -----
    §2.13. Outside the image the raw values are read through the reflect101 border
    (``dc|abcd|cb``), which maps a site to one of the same colour: reflecting about the edge
    site moves an even distance. The three planes are the normalised convolutions

    .. math:: R = K_{RB} * (M_R\\, I),\\quad G = K_G * (M_G\\, I),\\quad B = K_{RB} * (M_B\\, I),

    with the masks M of the sites of each colour and
    :math:`K_{RB} = \\frac14\\begin{bmatrix}1&2&1\\\\2&4&2\\\\1&2&1\\end{bmatrix}`,
    :math:`K_G = \\frac14\\begin{bmatrix}0&1&0\\\\1&4&1\\\\0&1&0\\end{bmatrix}`; the weights
    that fall on sites of the right colour always sum to 1. Away from the border the result
    equals OpenCV's ``cv2.cvtColor(raw, cv2.COLOR_Bayer<XY>2RGB)`` (names in
    :data:`OPENCV_BAYER_NAMES`). Interpolating across an edge mixes values from both sides
    at slightly different places in each channel, hence the colour fringes ("zipper")
    along sharp edges and false colours on fine patterns.

    Examples
    --------
    >>> raw = bayer_mosaic(np.ones((4, 6, 3)) * [0.2, 0.5, 0.9], "GRBG")
    >>> bool(np.allclose(demosaic_bilinear(raw, "GRBG"), [0.2, 0.5, 0.9]))
    True
    """
    img = as_float_array(raw, "raw", ndim=2)
    if img.shape[0] < 2 or img.shape[1] < 2:
        raise ValueError(f"raw must be at least 2×2 (one whole Bayer block), got shape {img.shape}")
    _check_pattern(pattern)
    h, w = img.shape
    padded = np.pad(img, 1, mode="reflect")  # numpy's "reflect" is reflect101
    sites = channel_map(pattern, h + 2, w + 2, offset=-1)
    out = np.empty((h, w, 3))
    k_rb = ((0.25, 0.5, 0.25), (0.5, 1.0, 0.5), (0.25, 0.5, 0.25))
    k_g = ((0.0, 0.25, 0.0), (0.25, 1.0, 0.25), (0.0, 0.25, 0.0))
    for channel, kernel in ((0, k_rb), (1, k_g), (2, k_rb)):
        plane = np.where(sites == channel, padded, 0.0)
        acc = np.zeros((h, w))
        for m in range(3):
            for n in range(3):
                if kernel[m][n]:
                    acc += kernel[m][n] * plane[m: m + h, n: n + w]
        measured = sites[1:-1, 1:-1] == channel
        acc[measured] = img[measured]
        out[:, :, channel] = acc
    return out
