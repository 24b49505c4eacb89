"""A small CNN trained with the layers of this package (for §11.6's transfer-learning experiments).

``conv3×3 – BN – ReLU – maxpool2 – conv3×3 – BN – ReLU – maxpool2 – GAP – linear``, trained by
mini-batch SGD with momentum on the mean cross-entropy (``cvkit.learn.cross_entropy``). Layers
are called through the registry, so ``with cvkit.use("student"):`` trains it on a student's
layers. Not graded: a tool for the notebooks and ``benchmarks/train_small_cnn.py``.
"""
from __future__ import annotations

import copy
import time
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._threads import single_thread
from .._validation import as_float_array, as_rng, check_allocation, check_int, check_real, check_size
from ..registry import implementation
from ._conv import check_conv_cost

__all__ = ["SmallCNN"]

_BN_KEYS = ("gamma", "beta", "running_mean", "running_var")
#: the learnable parameters of each part
BLOCK1 = ("w1", "gamma1", "beta1")
BLOCK2 = ("w2", "gamma2", "beta2")
HEAD = ("W", "b")
#: the most epochs :meth:`SmallCNN.fit` accepts
MAX_EPOCHS = 100_000


class SmallCNN:
    """``conv–BN–ReLU–pool`` ×2, global average pooling and a linear classifier.

    Parameters
    ----------
    classes : int
        Outputs of the linear head.
    channels : (int, int)
        Filters of the two convolutions.
    in_channels : int
        Channels of the input images (1 for the digits).
    rng : Generator, int or None
        Seed of the initial weights (He initialisation for the convolutions, small random
        head).

    Every weight array (``channels[1] × channels[0] × 3 × 3``, ...) must fit in 2 GiB (cvkit's
    limit for one array), else ``ValueError`` naming ``channels``, ``in_channels`` or
    ``classes``.

    Attributes
    ----------
    params : dict of arrays
        ``w1``, ``gamma1``, ``beta1``, ``running_mean1``, ``running_var1``, the same with 2,
        and the head ``W`` (D, classes), ``b``. Convolutions have no bias (BN follows them).
    """

    def __init__(self, classes: int = 10, channels: Sequence[int] = (16, 32), in_channels: int = 1,
                 rng: np.random.Generator | int | None = None) -> None:
        if isinstance(channels, (str, bytes)) or not hasattr(channels, "__len__") or len(channels) != 2:
            raise TypeError(f"channels must be a pair of ints (filters of the two convolutions), got {channels!r}")
        c1, c2 = (check_int(c, "channels", minimum=1) for c in channels)
        in_channels = check_int(in_channels, "in_channels", minimum=1)
        check_allocation((c1, in_channels, 3, 3), "channels" if c1 >= in_channels else "in_channels",
                         what="the first convolution's weights")
        check_allocation((c2, c1, 3, 3), "channels", what="the second convolution's weights")
        g = as_rng(rng)
        p = {
            "w1": g.standard_normal((c1, in_channels, 3, 3)) * np.sqrt(2.0 / (9 * in_channels)),
            "w2": g.standard_normal((c2, c1, 3, 3)) * np.sqrt(2.0 / (9 * c1)),
        }
        for i, c in ((1, c1), (2, c2)):
            p[f"gamma{i}"], p[f"beta{i}"] = np.ones(c), np.zeros(c)
            p[f"running_mean{i}"], p[f"running_var{i}"] = np.zeros(c), np.ones(c)
        self.params = p
        self.new_head(classes, rng=g)

    # ---------------------------------------------------------------------------------------
    def new_head(self, classes: int, rng: np.random.Generator | int | None = None) -> SmallCNN:
        """Replace the linear classifier by a fresh one with ``classes`` outputs (≥ 1; the
        ``(channels[1], classes)`` weights must fit in 2 GiB)."""
        classes = check_int(classes, "classes", minimum=1)
        g = as_rng(rng)
        d = self.params["w2"].shape[0]
        check_allocation((d, classes), "classes", what="the weights of the linear head")
        self.params["W"] = g.standard_normal((d, int(classes))) * np.sqrt(1.0 / d)
        self.params["b"] = np.zeros(int(classes))
        return self

    def copy(self) -> SmallCNN:
        return copy.deepcopy(self)

    def _images(self, X: ArrayLike, name: str = "X") -> np.ndarray:
        """``X`` as a batch ``(N, C, H, W)``, after checking that the images survive the two
        poolings and that every layer's arrays fit in memory (errors name ``name``)."""
        X = as_float_array(X, name, ndim=(3, 4))
        x = X[:, None] if X.ndim == 3 else X
        n, c, h, w = x.shape
        if c != self.params["w1"].shape[1]:
            raise ValueError(f"{name} must have {self.params['w1'].shape[1]} channel(s), got shape {X.shape}")
        if min(h, w) < 4:
            raise ValueError(f"{name} must hold images of at least 4 × 4 pixels (two 2 × 2 poolings), got shape {X.shape}")
        ho, wo = check_conv_cost(x.shape, self.params["w1"].shape, (1, 1), (1, 1), (name, "w1", name))
        c1 = self.params["w1"].shape[0]
        check_allocation((n, c1, ho, wo, 4), name, what="the first pooling's windows")
        check_conv_cost((n, c1, ho // 2, wo // 2), self.params["w2"].shape, (1, 1), (1, 1), (name, "w2", name))
        return x

    def _features(self, x: np.ndarray, training: bool, caches: dict[str, Any]) -> np.ndarray:
        conv = implementation("nn.conv2d_forward")
        bn = implementation("nn.batchnorm2d_forward")
        relu = implementation("nn.relu_forward")
        pool = implementation("nn.maxpool2d_forward")
        p = self.params
        h = x
        for i in (1, 2):
            w = p[f"w{i}"]
            h, caches[f"conv{i}"] = conv(h, w, np.zeros(w.shape[0]), stride=1, padding=1)
            h, caches[f"bn{i}"] = bn(h, *(p[f"{k}{i}"] for k in _BN_KEYS), training)
            if training:
                p[f"running_mean{i}"] = np.asarray(caches[f"bn{i}"]["running_mean"])
                p[f"running_var{i}"] = np.asarray(caches[f"bn{i}"]["running_var"])
            h, caches[f"relu{i}"] = relu(h)
            h, caches[f"pool{i}"] = pool(h, 2, 2)
        h, caches["gap"] = implementation("nn.global_avg_pool_forward")(h)
        return h

    def features(self, X: ArrayLike) -> np.ndarray:
        """The 'representation' of §11.6: GAP features ``(N, channels[1])`` in evaluation mode."""
        with single_thread():
            return self._features(self._images(X), False, {})

    def scores(self, X: ArrayLike, training: bool = False, caches: dict[str, Any] | None = None) -> np.ndarray:
        """Class scores ``(N, classes)``; ``caches`` (a dict) receives every layer's cache."""
        caches = {} if caches is None else caches
        with single_thread():
            return self._scores(self._images(X), training, caches)

    def _scores(self, x: np.ndarray, training: bool, caches: dict[str, Any]) -> np.ndarray:
        h = self._features(x, training, caches)
        out, caches["linear"] = implementation("nn.linear_forward")(h, self.params["W"], self.params["b"])
        return out

    def predict(self, X: ArrayLike) -> np.ndarray:
        return np.argmax(self.scores(X), axis=1)

    def accuracy(self, X: ArrayLike, y: ArrayLike) -> float:
        return float(np.mean(self.predict(X) == np.asarray(y)))

    def gradients(self, dscores: np.ndarray, caches: dict[str, Any]) -> dict[str, np.ndarray]:
        """Gradients of every learnable parameter from ∂L/∂scores."""
        g: dict[str, np.ndarray] = {}
        dh, g["W"], g["b"] = implementation("nn.linear_backward")(dscores, caches["linear"])
        dh = implementation("nn.global_avg_pool_backward")(dh, caches["gap"])
        for i in (2, 1):
            dh = implementation("nn.maxpool2d_backward")(dh, caches[f"pool{i}"])
            dh = implementation("nn.relu_backward")(dh, caches[f"relu{i}"])
            dh, g[f"gamma{i}"], g[f"beta{i}"] = implementation("nn.batchnorm2d_backward")(dh, caches[f"bn{i}"])
            dh, g[f"w{i}"], _ = implementation("nn.conv2d_backward")(dh, caches[f"conv{i}"])
        return g

    # ---------------------------------------------------------------------------------------
    def fit(self, X: ArrayLike, y: ArrayLike, epochs: int = 10, lr: float = 0.1, batch_size: int = 32,
            momentum: float = 0.9, weight_decay: float = 5e-4, trainable: Iterable[str] | None = None,
            shift: int = 0, rng: np.random.Generator | int | None = None, X_val: ArrayLike | None = None,
            y_val: ArrayLike | None = None, lr_final: float | None = None) -> dict[str, Any]:
        """Mini-batch SGD with momentum on the mean cross-entropy (+ weight decay).

        Parameters
        ----------
        X : (N, H, W) or (N, C, H, W) array_like
        y : (N,) int array_like
        epochs : int
            Passes over ``X``, 0 ≤ epochs ≤ :data:`MAX_EPOCHS` (100 000).
        lr, batch_size, momentum, weight_decay : float, int, float, float
            Learning rate (> 0), samples per step (≥ 1), momentum and weight decay (≥ 0).
        trainable : iterable of str, optional
            Names of the parameters to update (default all learnable ones): ``("W", "b")``
            trains the head of a frozen feature extractor. Frozen batch norms run in
            evaluation mode (their statistics stay those of the pre-training).
        shift : int
            Random translations of up to ``shift`` pixels (zero fill) as data augmentation,
            0 ≤ shift ≤ min(H, W) (a larger shift only moves more images out of sight).
        X_val, y_val : optional
            Evaluated after every epoch.
        lr_final : float, optional
            Cosine decay of the learning rate from ``lr`` (first epoch) to ``lr_final`` (last
            epoch); constant ``lr`` when None.

        Returns
        -------
        dict
            ``loss`` (mean training loss per epoch), ``val`` (validation accuracy per epoch,
            if given) and ``seconds``.
        """
        x = self._images(X)
        labels = np.asarray(y, dtype=np.int64)
        epochs = check_size(epochs, "epochs", minimum=0, maximum=MAX_EPOCHS)
        batch_size = check_int(batch_size, "batch_size", minimum=1)
        lr = check_real(lr, "lr", positive=True)
        momentum = check_real(momentum, "momentum", nonnegative=True)
        weight_decay = check_real(weight_decay, "weight_decay", nonnegative=True)
        shift = check_size(shift, "shift", minimum=0, maximum=min(x.shape[2:]))
        x_val = None if X_val is None else self._images(X_val, "X_val")
        names = BLOCK1 + BLOCK2 + HEAD if trainable is None else tuple(trainable)
        frozen_features = not any(n in names for n in BLOCK1 + BLOCK2)
        g = as_rng(rng)
        history: dict[str, Any] = {"loss": [], "val": []}
        if lr_final is None:
            rates = [lr] * epochs
        else:
            lr_final = check_real(lr_final, "lr_final", nonnegative=True)
            rates = [lr_final + 0.5 * (lr - lr_final) * (1 + np.cos(np.pi * e / max(epochs - 1, 1)))
                     for e in range(epochs)]
        with single_thread():
            self._fit(x, labels, rates, batch_size, momentum, weight_decay, names, frozen_features, shift, g,
                      x_val, y_val, history)
        return history

    def _fit(self, X: np.ndarray, y: np.ndarray, rates: list[float], batch_size: int, momentum: float,
             weight_decay: float, names: tuple[str, ...], frozen_features: bool, shift: int,
             g: np.random.Generator, X_val: np.ndarray | None, y_val: ArrayLike | None,
             history: dict[str, Any]) -> None:
        from ..learn import cross_entropy

        velocity = {k: np.zeros_like(self.params[k]) for k in names}
        start = time.perf_counter()
        n = len(X)
        for lr in rates:
            order = g.permutation(n)
            total = 0.0
            for s in range(0, n, batch_size):
                idx = order[s : s + batch_size]
                if len(idx) < 2:
                    continue
                xb = X[idx]
                if shift:
                    xb = _random_shift(xb, shift, g)
                caches: dict[str, Any] = {}
                scores = self._scores(xb, not frozen_features, caches)
                loss, dscores = cross_entropy(scores, y[idx])
                total += loss * len(idx)
                grads = self.gradients(dscores, caches)
                for k in names:
                    step = grads[k] + (weight_decay * self.params[k] if k.startswith(("w", "W")) else 0.0)
                    velocity[k] = momentum * velocity[k] - lr * step
                    self.params[k] = self.params[k] + velocity[k]
            history["loss"].append(total / n)
            if X_val is not None:
                predicted = np.argmax(self._scores(X_val, False, {}), axis=1)
                history["val"].append(float(np.mean(predicted == np.asarray(y_val))))
        history["seconds"] = time.perf_counter() - start


def _random_shift(x: np.ndarray, shift: int, g: np.random.Generator) -> np.ndarray:
    """Each image translated by (dy, dx) ∈ [−shift, shift]², zero fill."""
    n, c, h, w = x.shape
    padded = np.pad(x, ((0, 0), (0, 0), (shift, shift), (shift, shift)))
    dy = np.asarray(g.integers(0, 2 * shift + 1, n))  # asarray: NumPy's stubs say a scalar
    dx = np.asarray(g.integers(0, 2 * shift + 1, n))
    rows = dy[:, None] + np.arange(h)[None, :]
    cols = dx[:, None] + np.arange(w)[None, :]
    return padded[np.arange(n)[:, None, None, None], np.arange(c)[None, :, None, None],
                  rows[:, None, :, None], cols[:, None, None, :]]
