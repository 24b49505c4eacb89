"""Least-squares test problems for grading ``levenberg_marquardt``: residual functions (and
their Jacobians) described entirely by data.

A :class:`Residuals` is a ``dict`` — ``{"kind": ..., parameters as arrays}`` — that is also
callable: ``r = problem(x)``. Because it is nothing but data it can be copied, compared,
printed, and encoded by the grader's JSON wire format (as a plain dict). The check of
``calibration.levenberg_marquardt`` declares :func:`least_squares_call` as its
:attr:`cvkit.grading.Check.call`: wherever a case runs — here, or in the isolated worker of the
trusted grader, which receives plain dicts — it rebuilds the callables with :func:`rebuild`
and only then calls the candidate. The evaluation code below uses NumPy only.

Kinds (x is the parameter vector):

============ ========================================================= ======================
kind          residuals                                                 minimum
============ ========================================================= ======================
linear        M·x − b                                                   least squares, cost ≥ 0
rosenbrock    (a·(x1 − x0²), 1 − x0)                                   (1, 1), cost 0
circle        ‖p_i − (x0, x1)‖ − x2 for points p_i                     geometric circle fit
exponential   x0·exp(x1·t_i) + x2 − y_i                                curve fit
arctan        arctan(x − c)                                            c, cost 0 (Gauss–Newton
                                                                       diverges from |x − c| > 1.4)
projective    π(H(x)·(s_i, 1)) − d_i, H = [x, 1] as 3×3                 homography fit, 8 params
============ ========================================================= ======================
"""
from __future__ import annotations

import numpy as np

__all__ = ["Residuals", "Jacobian", "rebuild", "least_squares_call", "KINDS"]

KINDS = ("linear", "rosenbrock", "circle", "exponential", "arctan", "projective")

_DESCRIPTIONS = {
    "linear": "r(x) = M·x − b",
    "rosenbrock": "r(x) = (a·(x₁ − x₀²), 1 − x₀)  (Rosenbrock)",
    "circle": "r_i(x) = ‖p_i − (x₀, x₁)‖ − x₂  (circle through points)",
    "exponential": "r_i(x) = x₀·exp(x₁·t_i) + x₂ − y_i  (exponential fit)",
    "arctan": "r(x) = arctan(x − c)",
    "projective": "r_i(x) = π(H·(s_i, 1)) − d_i, H = [x₀..x₇, 1]  (homography fit)",
}


def _arrays(data: dict) -> dict:
    return {k: (v if k == "kind" else np.asarray(v, dtype=np.float64)) for k, v in data.items()}


class _Problem(dict):
    """Common part: a dict of data with value semantics."""

    def __init__(self, kind: str, **params):
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        super().__init__(kind=kind, **{k: np.asarray(v, dtype=np.float64) for k, v in params.items()})

    def __eq__(self, other):
        return (type(other) is type(self) and self.keys() == other.keys() and self["kind"] == other["kind"]
                and all(np.array_equal(self[k], other[k]) for k in self if k != "kind"))

    def __ne__(self, other):
        return not self == other

    __hash__ = None

    def __deepcopy__(self, memo):
        return type(self)(self["kind"], **{k: np.array(v) for k, v in self.items() if k != "kind"})

    def __copy__(self):
        return self.__deepcopy__({})

    def __reduce__(self):
        return (_restore, (type(self).__name__, dict(self)))

    def _p(self):
        return _arrays(self)


def _restore(name: str, data: dict):
    return {"Residuals": Residuals, "Jacobian": Jacobian}[name](**data)


class Residuals(_Problem):
    """A residual function r(x) given by data; call it with a parameter vector."""

    def __repr__(self):
        return _DESCRIPTIONS[self["kind"]]

    def __call__(self, x):
        x = np.asarray(x, dtype=np.float64).ravel()
        p = self._p()
        kind = self["kind"]
        if kind == "linear":
            return p["M"] @ x - p["b"]
        if kind == "rosenbrock":
            return np.array([p["a"] * (x[1] - x[0] ** 2), 1.0 - x[0]])
        if kind == "circle":
            points = p["points"]
            return np.hypot(points[:, 0] - x[0], points[:, 1] - x[1]) - x[2]
        if kind == "exponential":
            with np.errstate(over="ignore", invalid="ignore"):
                return x[0] * np.exp(x[1] * p["t"]) + x[2] - p["y"]
        if kind == "arctan":
            return np.arctan(x - p["c"])
        if kind == "projective":
            H = np.append(x, 1.0).reshape(3, 3)
            s = p["src"]
            with np.errstate(divide="ignore", invalid="ignore"):
                m = s @ H[:, :2].T + H[:, 2]
                return (m[:, :2] / m[:, 2:] - p["dst"]).ravel()
        raise ValueError(kind)  # pragma: no cover


class Jacobian(_Problem):
    """The analytic Jacobian ∂r/∂x of the :class:`Residuals` with the same data."""

    def __repr__(self):
        return "J(x) = ∂r/∂x of " + _DESCRIPTIONS[self["kind"]]

    def __call__(self, x):
        x = np.asarray(x, dtype=np.float64).ravel()
        p = self._p()
        kind = self["kind"]
        if kind == "linear":
            return p["M"].copy()
        if kind == "rosenbrock":
            return np.array([[-2.0 * p["a"] * x[0], p["a"]], [-1.0, 0.0]])
        if kind == "circle":
            points = p["points"]
            dx, dy = x[0] - points[:, 0], x[1] - points[:, 1]
            distance = np.hypot(dx, dy)
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.column_stack([dx / distance, dy / distance, -np.ones(len(points))])
        if kind == "exponential":
            t = p["t"]
            with np.errstate(over="ignore", invalid="ignore"):
                e = np.exp(x[1] * t)
                return np.column_stack([e, x[0] * t * e, np.ones_like(t)])
        if kind == "arctan":
            return np.diag(1.0 / (1.0 + (x - p["c"]) ** 2))
        if kind == "projective":
            H = np.append(x, 1.0).reshape(3, 3)
            s = p["src"]
            sx, sy = s[:, 0], s[:, 1]
            w = H[2, 0] * sx + H[2, 1] * sy + 1.0
            u = (H[0, 0] * sx + H[0, 1] * sy + H[0, 2]) / w
            v = (H[1, 0] * sx + H[1, 1] * sy + H[1, 2]) / w
            J = np.zeros((2 * len(s), 8))
            J[0::2, 0], J[0::2, 1], J[0::2, 2] = sx / w, sy / w, 1.0 / w
            J[1::2, 3], J[1::2, 4], J[1::2, 5] = sx / w, sy / w, 1.0 / w
            J[0::2, 6], J[0::2, 7] = -u * sx / w, -u * sy / w
            J[1::2, 6], J[1::2, 7] = -v * sx / w, -v * sy / w
            return J
        raise ValueError(kind)  # pragma: no cover


def rebuild(data: dict, jacobian: bool = False):
    """A :class:`Residuals` (or :class:`Jacobian`) from its plain-dict form (e.g. decoded JSON)."""
    data = dict(data)
    kind = data.pop("kind")
    return (Jacobian if jacobian else Residuals)(kind, **data)


def least_squares_call(candidate, residuals, x0, *args, **kwargs):
    """:attr:`cvkit.grading.Check.call` of ``calibration.levenberg_marquardt``.

    A case holds the residual function (and the Jacobian, positional or keyword) as data;
    rebuild them as callables and return ``candidate(residuals, x0, ...)``. The reference and
    every mistake of the bank are called the same way.
    """
    args = list(args)
    if args and args[0] is not None:
        args[0] = rebuild(args[0], jacobian=True)
    if kwargs.get("jacobian") is not None:
        kwargs["jacobian"] = rebuild(kwargs["jacobian"], jacobian=True)
    return candidate(rebuild(residuals), x0, *args, **kwargs)
