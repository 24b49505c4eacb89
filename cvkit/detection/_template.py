"""Template matching (§6.0.1–6.0.2): slide the model over the target image and score every
placement with a pixel-based (dis)similarity — SSD, SAD, NCC or ZNCC — then pick the best.

Vectorised: the cross-correlation term of SSD, NCC and ZNCC is one FFT product (or, for small
templates, a loop over the template's taps, each a whole-image multiply-add); the window sums
of the normalisations come from running sums; SAD, which has no such shortcut, loops over the
template's taps. Windows without contrast (zero norm or zero variance) are found exactly with
a sliding minimum and maximum, so they score 0 without NaN or division warnings.
"""
from __future__ import annotations

from typing import Callable, Literal, cast

import numpy as np
from numpy.typing import ArrayLike

from .._fft import correlate_valid as correlate_valid_fft
from .._fft import fft_pays
from .._validation import as_float_array, check_work
from ..registry import algorithm

__all__ = ["match_template", "best_match"]

MEASURES = ("ssd", "sad", "ncc", "zncc")
Measure = Literal["ssd", "sad", "ncc", "zncc"]
#: relative size under which a norm or a variance counts as zero (see match_template)
FLAT = 1e-12


def _check_measure(measure: object) -> Measure:
    if not isinstance(measure, str) or measure not in MEASURES:
        raise ValueError(f"measure must be one of {', '.join(map(repr, MEASURES))}, got {measure!r}")
    return cast(Measure, measure)


def _window_sums(a: np.ndarray, h: int, w: int) -> np.ndarray:
    """``S[i, j] = sum(a[i:i+h, j:j+w])`` for every valid placement, by running sums along
    each axis in turn (rounding grows with one row or column, not with the whole image)."""
    c = np.cumsum(a, axis=1)
    rows = c[:, w - 1:].copy()
    rows[:, 1:] -= c[:, :-w]
    c = np.cumsum(rows, axis=0)
    out = c[h - 1:].copy()
    out[1:] -= c[:-h]
    return out


def _sliding(a: np.ndarray, size: int, axis: int, op: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """Sliding ``op`` (np.maximum / np.minimum) over windows of ``size`` along ``axis``, by
    doubling: log2(size) whole-array steps."""
    out = a
    span = 1
    while span * 2 <= size:
        n = out.shape[axis] - span
        out = op(out.take(np.arange(n), axis=axis), out.take(np.arange(span, span + n), axis=axis))
        span *= 2
    if span < size:
        n = out.shape[axis] - (size - span)
        out = op(out.take(np.arange(n), axis=axis), out.take(np.arange(size - span, size - span + n), axis=axis))
    return out


def _window_range_is_zero(a: np.ndarray, h: int, w: int) -> np.ndarray:
    """Exactly: is every value of the window ``a[i:i+h, j:j+w]`` the same?"""
    hi = _sliding(_sliding(a, w, 1, np.maximum), h, 0, np.maximum)
    lo = _sliding(_sliding(a, w, 1, np.minimum), h, 0, np.minimum)
    return hi == lo


def _correlate_valid(img: np.ndarray, tpl: np.ndarray) -> np.ndarray:
    """``C[i, j] = sum_{m,n} I[i+m, j+n]·T[m, n]`` over the valid placements."""
    H, W = img.shape
    h, w = tpl.shape
    ho, wo = H - h + 1, W - w + 1
    if not fft_pays(h * w, (ho, wo), (H, W)):
        out = np.zeros((ho, wo))
        for m in range(h):
            for n in range(w):
                if tpl[m, n] != 0.0:
                    out += tpl[m, n] * img[m:m + ho, n:n + wo]
        return out
    return correlate_valid_fft(img, tpl)


def _as_pair(image: ArrayLike, template: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    img = as_float_array(image, "image", ndim=2)
    tpl = as_float_array(template, "template", ndim=2)
    if tpl.shape[0] > img.shape[0] or tpl.shape[1] > img.shape[1]:
        raise ValueError(f"template must fit in the image: template {tpl.shape}, image {img.shape}")
    return img, tpl


@algorithm("detection.match_template", section="6.0.2", check="cvkit.detection.checks:match_template")
def match_template(image: ArrayLike, template: ArrayLike, measure: Measure = "zncc") -> np.ndarray:
    """Score every placement of ``template`` over ``image``.

    Parameters
    ----------
    image : (H, W) array_like
        Target image, any real dtype, finite values (not rescaled).
    template : (h, w) array_like
        The model, ``h <= H`` and ``w <= W``. For ``sad``, which visits every template pixel
        at every placement, ``3·h·w·(H − h + 1)(W − w + 1)`` may be at most
        ``cvkit._validation.MAX_WORK`` (2**36, about a minute; ``ValueError`` naming
        ``template``); the other measures use an FFT when that is cheaper.
    measure : {"zncc", "ncc", "ssd", "sad"}
        ``ssd``: Σ (I − T)²; ``sad``: Σ |I − T| (both dissimilarities: lower is better);
        ``ncc``: Σ I·T / (‖I‖·‖T‖), the cosine of the angle between the window and the
        template seen as vectors; ``zncc``: the same after subtracting each one's mean, i.e.
        the correlation coefficient (similarities in [−1, 1]: higher is better).

    Returns
    -------
    (H − h + 1, W − w + 1) float64 ndarray
        ``S[i, j]`` scores the window whose top-left pixel is ``(x = j, y = i)``, i.e.
        ``image[i:i+h, j:j+w]`` against ``template``.

    Notes
    -----
    §6.0.2. With ``I`` the window and ``n = h·w``:

    - ``ssd``: ``Σ I² − 2 Σ I·T + Σ T²`` (clipped at 0 against rounding), after subtracting
      the template's rounded mean from image and template (the same value: SSD unchanged, its
      sums small for an image far from 0);
    - ``ncc``: ``Σ I·T / sqrt(Σ I² · Σ T²)``; invariant to a gain ``I → a·I`` (a > 0);
    - ``zncc``: ``Σ (I − μ_I)(T − μ_T) / sqrt(Σ (I − μ_I)² · Σ (T − μ_T)²)``; invariant to
      gain and offset ``I → a·I + b`` (a > 0).

    Windows without contrast have no defined NCC/ZNCC; their score is **0**, without
    warnings: for ``ncc`` a window whose mean square is at most 1e-12 times the mean square of
    the image (an all-zero window: below that, the sliding sums' rounding decides) and an
    all-zero template (a template of any other size keeps its scores, as NCC ignores the
    template's gain); for ``zncc`` a window (or template)
    whose variance is at most 1e-12 times its own mean square (a constant window). Exactly
    constant (or zero) windows are found exactly, with a sliding minimum and maximum, not from
    rounded sums. Scores are clipped to [−1, 1].

    Precision: the sliding sums of ``zncc`` are taken about the image's mean, so a
    window whose spread is tiny beside its distance from that mean (a texture of 1e-3 on an
    offset of 1e6, a region scaled by 1e-8 in an image in [0, 1]) keeps only about
    ``1e-16·(distance / spread)²`` of relative precision in its score. Images in ordinary
    ranges (uint8, [0, 1]) are far from that; ``ssd`` subtracts the template's mean first and
    ``sad`` sums each window directly.

    Equals ``cv2.matchTemplate`` with ``TM_SQDIFF`` (ssd), ``TM_CCORR_NORMED`` (ncc) and
    ``TM_CCOEFF_NORMED`` (zncc), and ``skimage.feature.match_template`` (zncc), away from
    flat windows, where those libraries return other conventions (OpenCV 1 or 0, scikit-image
    0 or NaN).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.array([[0, 0, 0, 0],
    ...                 [0, 1, 2, 0],
    ...                 [0, 3, 4, 0]])
    >>> tpl = np.array([[1, 2], [3, 4]])
    >>> match_template(img, tpl, "ssd")
    array([[23., 13., 22.],
           [12.,  0., 22.]])
    >>> s = match_template(10 * img + 5, tpl)       # zncc ignores gain and offset
    >>> s.round(3)
    array([[ 0.775,  0.944,  0.258],
           [ 0.73 ,  1.   , -0.135]])
    """
    img, tpl = _as_pair(image, template)
    measure = _check_measure(measure)
    h, w = tpl.shape
    n = h * w
    if measure == "sad":
        ho, wo = img.shape[0] - h + 1, img.shape[1] - w + 1
        check_work(3 * n * ho * wo, "template", what=f"SAD of a {h}×{w} template at {ho}×{wo} placements")
        out = np.zeros((ho, wo))
        scratch = np.empty((ho, wo))
        for m in range(h):
            for k in range(w):
                np.subtract(img[m:m + ho, k:k + wo], tpl[m, k], out=scratch)
                np.abs(scratch, out=scratch)
                out += scratch
        return out
    if measure == "ssd":
        # Σ (I − T)² does not change when I and T lose the same offset c: taking the
        # template's mean, rounded (integer images stay integer, so exact), keeps the three
        # sums small for an image far from 0 (1e6 + small texture loses nothing to rounding)
        offset = float(np.round(tpl.mean()))
        if offset != 0.0 and np.isfinite(offset):
            img, tpl = img - offset, tpl - offset
        cross = _correlate_valid(img, tpl)
        out = _window_sums(img * img, h, w) - 2.0 * cross + float(np.sum(tpl * tpl))
        return np.maximum(out, 0.0)
    if measure == "ncc":
        cross = _correlate_valid(img, tpl)
        energy = np.maximum(_window_sums(img * img, h, w), 0.0)
        limit = FLAT * n * float(np.mean(img * img))
        largest = _sliding(_sliding(np.abs(img), w, 1, np.maximum), h, 0, np.maximum)
        zero = (energy <= limit) | (largest == 0.0)
        t_scale = float(np.max(np.abs(tpl)))
        if t_scale == 0.0:
            return np.zeros(energy.shape)
        if not 1e-150 < t_scale < 1e150:  # NCC ignores the template's gain: keep T² in range
            tpl = tpl / t_scale
            cross = _correlate_valid(img, tpl)
        t_energy = float(np.sum(tpl * tpl))
        with np.errstate(divide="ignore", invalid="ignore"):
            out = cross / np.sqrt(energy * t_energy)
        out[zero] = 0.0
        return np.clip(out, -1.0, 1.0)
    # zncc: centre the image (the score ignores offsets; rounding then scales with the contrast)
    tz = tpl - tpl.mean()
    t_var = float(np.sum(tz * tz))
    ho, wo = img.shape[0] - h + 1, img.shape[1] - w + 1
    if t_var <= FLAT * float(np.sum(tpl * tpl)) or np.all(tpl == tpl.flat[0]):
        return np.zeros((ho, wo))
    ic = img - img.mean()
    cross = _correlate_valid(ic, tz)
    s1 = _window_sums(ic, h, w)
    s2 = _window_sums(ic * ic, h, w)
    var = np.maximum(s2 - s1 * s1 / n, 0.0)
    # the window's own mean square: Σ(I)² with I = ic + mean
    mu = float(img.mean())
    own = s2 + 2.0 * mu * s1 + n * mu * mu
    flat = (var <= FLAT * own) | _window_range_is_zero(img, h, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = cross / np.sqrt(var * t_var)
    out[flat] = 0.0
    return np.clip(out, -1.0, 1.0)


@algorithm("detection.best_match", section="6.0.2", check="cvkit.detection.checks:best_match")
def best_match(scores: ArrayLike, measure: Measure) -> tuple[int, int]:
    """The best placement in a score map: the minimum for ssd/sad, the maximum for ncc/zncc.

    Parameters
    ----------
    scores : (H', W') array_like
        A score map from :func:`match_template`, finite values.
    measure : {"ssd", "sad", "ncc", "zncc"}
        The measure that made ``scores`` (says whether lower or higher is better).

    Returns
    -------
    (x, y) : tuple of two Python ints
        Column and row of the best score, i.e. the template's top-left corner. Ties go to the
        first in row-major order (the smallest y, then the smallest x), as ``np.argmin`` /
        ``np.argmax`` on the flattened map.

    Examples
    --------
    >>> import numpy as np
    >>> s = np.array([[3.0, 1.0, 2.0], [1.0, 5.0, 5.0]])
    >>> best_match(s, "ssd"), best_match(s, "zncc")
    ((1, 0), (1, 1))
    """
    s = as_float_array(scores, "scores", ndim=2)
    measure = _check_measure(measure)
    flat = int(np.argmin(s)) if measure in ("ssd", "sad") else int(np.argmax(s))
    y, x = divmod(flat, s.shape[1])
    return int(x), int(y)
