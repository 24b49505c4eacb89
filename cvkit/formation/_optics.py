"""Lenses (§2.8–2.10): the thin lens equation and the circle of confusion behind depth of field."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import check_real
from ..registry import algorithm
from ._common import Values, as_values, scalar_or_array

__all__ = ["thin_lens_image_distance", "blur_circle_diameter"]


@algorithm("formation.thin_lens_image_distance", section="2.8.1",
           check="cvkit.formation.checks:thin_lens_image_distance")
def thin_lens_image_distance(object_distance: ArrayLike, focal_length: float) -> Values:
    """Distance behind a thin lens at which a point at ``object_distance`` is in focus.

    Parameters
    ----------
    object_distance : float or array_like
        Distance :math:`d_S > 0` of the scene point from the lens, any shape; ``inf`` (a point
        at infinity) is allowed.
    focal_length : float
        Focal length :math:`f_L > 0`, in the same length unit.

    Returns
    -------
    float64 ndarray of the shape of ``object_distance`` (a NumPy float for a scalar)
        Image distance :math:`d_I`: ``focal_length`` for :math:`d_S = \\infty`, ``inf`` for
        :math:`d_S = f_L` (the rays leave the lens parallel), negative for
        :math:`d_S < f_L` (a virtual image on the object's side: a magnifying glass).

    Raises
    ------
    ValueError
        ``object_distance`` not > 0 (or NaN), ``focal_length`` not finite and > 0.

    Notes
    -----
    §2.8.1, the thin lens equation

    .. math:: \\frac{1}{d_S} + \\frac{1}{d_I} = \\frac{1}{f_L}
              \\quad\\Longrightarrow\\quad d_I = \\frac{f_L\\, d_S}{d_S - f_L}.

    As :math:`d_S` decreases from infinity to :math:`f_L`, :math:`d_I` grows from
    :math:`f_L` to infinity: to focus on closer objects the sensor moves away from the lens
    (§2.10).

    Examples
    --------
    >>> thin_lens_image_distance([np.inf, 150.0, 50.0, 25.0], 50.0)
    array([ 50.,  75.,  inf, -50.])
    """
    d_s = as_values(object_distance, "object_distance", allow_inf=True)
    f = check_real(focal_length, "focal_length", positive=True)
    if np.any(d_s <= 0):
        raise ValueError("object_distance must be > 0 (a point in front of the lens)")
    finite = np.isfinite(d_s)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d_i = f * d_s / (d_s - f)
        # f·dS can overflow where dI is finite (dS near the largest float): f / (1 − f/dS) there
        d_i = np.where(np.isinf(d_i), f / (1.0 - f / d_s), d_i)
    d_i = np.where(d_s == f, np.inf, d_i)
    d_i = np.where(finite, d_i, f)
    return scalar_or_array(d_i)


@algorithm("formation.blur_circle_diameter", section="2.8–2.9", check="cvkit.formation.checks:blur_circle_diameter")
def blur_circle_diameter(object_distance: ArrayLike, focus_distance: ArrayLike, focal_length: ArrayLike,
                         aperture_diameter: ArrayLike) -> Values:
    """Diameter of the blur circle (circle of confusion) of an out-of-focus point.

    Parameters
    ----------
    object_distance : float or array_like
        Distance :math:`d_O` of the scene point from the lens; ``> focal_length``, ``inf``
        allowed.
    focus_distance : float or array_like
        Object distance :math:`d_F` the lens is focused on (the sensor sits at its image
        distance); ``> focal_length``, ``inf`` allowed (focused at infinity).
    focal_length : float or array_like
        Focal length f > 0, finite.
    aperture_diameter : float or array_like
        Diameter D >= 0 of the effective aperture (set by the diaphragm), finite.
        All four broadcast together and share one length unit.

    Returns
    -------
    float64 ndarray of the broadcast shape (a NumPy float for scalars)
        Blur circle diameter c on the sensor, in the same unit (0 for points in focus).

    Raises
    ------
    ValueError
        A distance not larger than the focal length (or NaN), a focal length not > 0, an
        aperture < 0, or shapes that do not broadcast.

    Notes
    -----
    §2.8–2.9. The lens focused on :math:`d_F` puts the sensor at
    :math:`d_I(d_F) = f d_F / (d_F - f)`; a point at :math:`d_O` converges at
    :math:`d_I(d_O)` instead, and its cone of light, of base D at the lens, cuts the sensor in
    a disc of diameter :math:`D\\,|d_I(d_O) - d_I(d_F)| / d_I(d_O)` (similar triangles):

    .. math:: c = \\frac{D\\, f\\, |d_O - d_F|}{d_O\\,(d_F - f)}.

    The limits are used at infinity: :math:`c = D f / (d_F - f)` for
    :math:`d_O = \\infty`, :math:`c = D f / d_O` for :math:`d_F = \\infty`, 0 when both are
    infinite. c is proportional to D: closing the diaphragm shrinks every blur circle by
    the same factor and widens the range of distances whose circles stay below one pixel,
    the depth of field.

    Examples
    --------
    >>> # a 50 mm lens at f/2 (D = 25 mm) focused at 2 m; points at 1 m, 2 m, 4 m, infinity
    >>> blur_circle_diameter([1000.0, 2000.0, 4000.0, np.inf], 2000.0, 50.0, 25.0).round(4)
    array([0.641 , 0.    , 0.3205, 0.641 ])
    """
    d_o = as_values(object_distance, "object_distance", allow_inf=True)
    d_f = as_values(focus_distance, "focus_distance", allow_inf=True)
    f = as_values(focal_length, "focal_length")
    aperture = as_values(aperture_diameter, "aperture_diameter")
    try:
        d_o, d_f, f, aperture = np.broadcast_arrays(d_o, d_f, f, aperture)
    except ValueError:
        raise ValueError(
            "object_distance, focus_distance, focal_length and aperture_diameter must broadcast "
            f"together, got shapes {np.shape(object_distance)}, {np.shape(focus_distance)}, "
            f"{np.shape(focal_length)}, {np.shape(aperture_diameter)}"
        ) from None
    if np.any(f <= 0):
        raise ValueError("focal_length must be > 0")
    if np.any(aperture < 0):
        raise ValueError("aperture_diameter must be >= 0")
    if np.any(d_o <= f):
        raise ValueError("object_distance must be larger than focal_length (a real image)")
    if np.any(d_f <= f):
        raise ValueError("focus_distance must be larger than focal_length (a real image)")
    o_inf, f_inf = np.isinf(d_o), np.isinf(d_f)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        c = aperture * f * np.abs(d_o - d_f) / (d_o * (d_f - f))
        # a product that overflows (distances near the largest float): the same ratio in steps
        c = np.where(np.isfinite(aperture * f * np.abs(d_o - d_f)) & np.isfinite(d_o * (d_f - f)), c,
                     aperture * f / (d_f - f) * (np.abs(d_o - d_f) / d_o))
        c = np.where(o_inf & ~f_inf, aperture * f / (d_f - f), c)
        c = np.where(f_inf & ~o_inf, aperture * f / d_o, c)
        c = np.where(o_inf & f_inf, 0.0, c)
    return scalar_or_array(c)
