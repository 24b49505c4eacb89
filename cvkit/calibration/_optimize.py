"""Non-linear least squares by Levenberg–Marquardt (§8.3.4, §8.3.8), written with NumPy only."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_allocation, check_real, check_size
from ..registry import algorithm

__all__ = ["levenberg_marquardt"]

_EPS_STEP = np.sqrt(np.finfo(np.float64).eps)
#: the most iterations levenberg_marquardt accepts (each one solves the damped system and
#: evaluates the residuals once)
MAX_ITER = 100_000


def _residual_vector(residuals: Callable[[np.ndarray], ArrayLike], x: np.ndarray, where: str) -> np.ndarray:
    value = residuals(x.copy())
    try:
        r = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise TypeError(f"residuals({where}) must return an array of numbers, got {type(value).__name__}") from None
    return r


def _normal_equations(J: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gradient Jᵀr of ½‖r‖² and the Gauss–Newton matrix JᵀJ."""
    return J.T @ r, J.T @ J


def _damped_step(JTJ: np.ndarray, g: np.ndarray, mu: float) -> np.ndarray:
    """The solution δ of (JᵀJ + μ·diag(JᵀJ)) δ = −g, with a zero diagonal entry raised to
    1e-12 of the largest (to 1 if all are 0). Raises ``numpy.linalg.LinAlgError`` when the
    system is singular."""
    diagonal = np.diag(JTJ).copy()
    top = float(diagonal.max()) if diagonal.size else 0.0
    diagonal = np.maximum(diagonal, 1e-12 * top if top > 0 else 1.0)
    return np.linalg.solve(JTJ + mu * np.diag(diagonal), -g)


def _trial_step(residuals: Callable[[np.ndarray], ArrayLike], x: np.ndarray, step: np.ndarray, size: int,
                tol: float) -> tuple[bool, np.ndarray, np.ndarray, float]:
    """``(tiny, x + step, its residuals, its cost)``: the step is tiny when ‖δ‖ ≤ tol·(‖x‖ + tol);
    the cost is ½‖r‖², infinite when the residual vector's length is not ``size``."""
    tiny = bool(np.linalg.norm(step) <= tol * (np.linalg.norm(x) + tol))
    trial = x + step
    r_trial = _residual_vector(residuals, trial, "x")
    cost_trial = 0.5 * float(r_trial @ r_trial) if r_trial.size == size else np.inf
    return tiny, trial, r_trial, cost_trial


def _forward_jacobian(residuals: Callable[[np.ndarray], ArrayLike], x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Forward differences: column j is (r(x + h_j e_j) − r(x)) / h_j, h_j = √ε·max(1, |x_j|)."""
    J = np.empty((r.size, x.size))
    for j in range(x.size):                   # one residual evaluation per parameter
        h = _EPS_STEP * max(1.0, abs(x[j]))
        shifted = x.copy()
        shifted[j] += h
        h = shifted[j] - x[j]                 # the step actually represented in floating point
        J[:, j] = (_residual_vector(residuals, shifted, "x + h") - r) / h
    return J


@algorithm("calibration.levenberg_marquardt", section="8.3.4", check="cvkit.calibration.checks:levenberg_marquardt")
def levenberg_marquardt(residuals: Callable[[np.ndarray], ArrayLike], x0: ArrayLike,
                        jacobian: Callable[[np.ndarray], ArrayLike] | None = None, max_iter: int = 100,
                        tol: float = 1e-10) -> tuple[np.ndarray, dict[str, Any]]:
    """Minimise ½‖r(x)‖² by the Levenberg–Marquardt method.

    Parameters
    ----------
    residuals : callable
        ``residuals(x)`` → the residual vector r(x) (any shape; it is flattened) for a
        parameter vector ``x`` of shape (n,). It is always called with a fresh copy of x.
    x0 : (n,) array_like
        Starting point (finite). The Jacobian (m, n) and JᵀJ (n, n) may take at most 2 GiB
        each (``ValueError`` naming ``x0``, checked before they are built).
    jacobian : callable, optional
        ``jacobian(x)`` → the (m, n) matrix ∂r/∂x. Default: forward differences with steps
        h_j = √ε·max(1, |x_j|) (n extra residual evaluations per Jacobian).
    max_iter : int
        Largest number of iterations, 0 ≤ max_iter ≤ 100 000 (:data:`MAX_ITER`); each solves
        the damped normal equations once and tries the step.
    tol : float
        Tolerance of the three stopping tests (≥ 0).

    Returns
    -------
    x : (n,) float64 ndarray
        The best point found — never costlier than ``x0``.
    info : dict
        ``iterations`` (int, steps tried), ``cost`` (½‖r(x)‖²), ``converged`` (bool: a stopping
        test was met before ``max_iter``), ``gradient`` (‖Jᵀr‖∞ at the last Jacobian), ``mu``
        (the final damping factor).

    Raises
    ------
    ValueError
        A non-finite or non-1-D ``x0``, residuals that are not finite at ``x0``, a Jacobian of
        the wrong shape, negative ``max_iter`` or ``tol``.
    TypeError
        ``residuals`` or ``jacobian`` not callable.

    Notes
    -----
    §8.3.4: near a minimum, r(x + δ) ≈ r + Jδ, and minimising ‖r + Jδ‖² gives the
    Gauss–Newton step :math:`J^T J \\delta = -J^T r`, fast close to the solution but unsafe far
    from it (the linearisation is poor, the step can overshoot and increase the cost).
    Levenberg–Marquardt damps it,

    .. math:: (J^T J + \\mu\\, \\mathrm{diag}(J^T J))\\, \\delta = -J^T r,

    and adapts μ: a step that lowers the cost is taken and μ is divided by 10 (towards
    Gauss–Newton); a step that raises it is refused and μ is multiplied by 10 (towards a short
    gradient-descent step, scaled per parameter by Marquardt's diagonal, so parameters in
    pixels and in radians are treated alike). μ starts at 1e-3; a zero diagonal entry is
    raised to 1e-12 of the largest.

    It stops (``converged``) when the gradient is flat, ‖Jᵀr‖∞ ≤ tol; when an accepted step
    lowers the cost by less than the fraction tol; or when the step is tiny,
    ‖δ‖ ≤ tol·(‖x‖ + tol) (also for a refused step: nothing can be gained any more). It gives
    up after ``max_iter`` steps or when μ exceeds 1e16. Only improving steps are taken, so the
    result is never costlier than x0. On the test problems of the tests it reaches the same
    minimum as ``scipy.optimize.least_squares(method="lm")`` (MINPACK).

    Examples
    --------
    >>> import numpy as np
    >>> def rosenbrock(x):                      # minimum 0 at (1, 1)
    ...     return np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])
    >>> x, info = levenberg_marquardt(rosenbrock, [-1.2, 1.0])
    >>> np.round(x, 8), info["converged"], info["cost"] < 1e-20
    (array([1., 1.]), True, True)
    """
    if not callable(residuals):
        raise TypeError(f"residuals must be a callable r(x), got {type(residuals).__name__}")
    if jacobian is not None and not callable(jacobian):
        raise TypeError(f"jacobian must be a callable J(x) or None, got {type(jacobian).__name__}")
    x = as_float_array(x0, "x0", ndim=1).copy()
    max_iter = check_size(max_iter, "max_iter", minimum=0, maximum=MAX_ITER)
    tol = check_real(tol, "tol", nonnegative=True)
    r = _residual_vector(residuals, x, "x0")
    if r.size == 0 or not np.all(np.isfinite(r)):
        raise ValueError("residuals(x0) must return a non-empty vector of finite numbers")
    check_allocation((r.size, x.size), "x0", what="the Jacobian (len(residuals), len(x0))")
    check_allocation((x.size, x.size), "x0", what="JᵀJ")

    def jac(point: np.ndarray, res: np.ndarray) -> np.ndarray:
        if jacobian is None:
            return _forward_jacobian(residuals, point, res)
        J = np.asarray(jacobian(point.copy()), dtype=np.float64)
        if J.shape != (res.size, point.size):
            raise ValueError(f"jacobian(x) must have shape (m, n) = ({res.size}, {point.size}), got {J.shape}")
        return J

    cost = 0.5 * float(r @ r)
    g, JTJ = _normal_equations(jac(x, r), r)
    mu = 1e-3
    iterations = 0
    converged = bool(np.max(np.abs(g)) <= tol) if np.all(np.isfinite(g)) else False
    while not converged and iterations < max_iter and mu <= 1e16:
        iterations += 1
        try:
            step = _damped_step(JTJ, g, mu)
        except np.linalg.LinAlgError:
            mu *= 10.0
            continue
        tiny, trial, r_trial, cost_trial = _trial_step(residuals, x, step, r.size, tol)
        if np.isfinite(cost_trial) and cost_trial < cost:
            decrease = (cost - cost_trial) / cost
            x, r, cost = trial, r_trial, cost_trial
            mu = max(mu / 10.0, 1e-15)
            if decrease < tol or tiny:
                converged = True
                break
            g, JTJ = _normal_equations(jac(x, r), r)
            if np.max(np.abs(g)) <= tol:
                converged = True
        else:
            mu *= 10.0
            if tiny:
                converged = True
    info = {"iterations": int(iterations), "cost": float(cost), "converged": bool(converged),
            "gradient": float(np.max(np.abs(g))) if g.size else 0.0, "mu": float(mu)}
    return x, info
