"""A small CNN trained with the layers of this package (for §11.6's transfer-learning experiments).

``conv3×3 – BN – ReLU – maxpool2 – conv3×3 – BN – ReLU – maxpool2 – GAP – linear``, trained by
mini-batch SGD with momentum on the mean cross-entropy (``cvkit.learn.cross_entropy``). Layers
are called through the registry, so ``with cvkit.use("student"):`` trains it on a student's
layers. Not graded: a tool for the notebooks and ``benchmarks/train_small_cnn.py``.
"""
from __future__ import annotations

import contextlib
import copy
import time

import numpy as np

try:  # installed with scikit-learn, which the digits come from
    from threadpoolctl import threadpool_limits as _threadpool_limits
except ImportError:  # pragma: no cover
    _threadpool_limits = None

from .._validation import as_float_array, as_rng, check_int, check_real
from ..registry import implementation

__all__ = ["SmallCNN"]

_BN_KEYS = ("gamma", "beta", "running_mean", "running_var")
#: the learnable parameters of each part
BLOCK1 = ("w1", "gamma1", "beta1")
BLOCK2 = ("w2", "gamma2", "beta2")
HEAD = ("W", "b")


def single_thread():
    """BLAS limited to one thread: the matrices of a small CNN are tiny, and extra threads only
    add overhead (on a busy 2-core machine a product of 512×144 by 144×32 took 16 ms with
    threads and 0.5 ms without)."""
    return _threadpool_limits(1) if _threadpool_limits is not None else contextlib.nullcontext()


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

    Attributes
    ----------
    params : dict of arrays
        ``w1``, ``gamma1``, ``beta1``, ``running_mean1``, ``running_var1``, the same with 2,
        and the head ``W`` (D, classes), ``b``. Convolutions have no bias (BN follows them).
    """

    def __init__(self, classes=10, channels=(16, 32), in_channels=1, rng=None):
        classes = check_int(classes, "classes", minimum=1)
        c1, c2 = (check_int(c, "channels", minimum=1) for c in channels)
        in_channels = check_int(in_channels, "in_channels", minimum=1)
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
    def new_head(self, classes, rng=None):
        """Replace the linear classifier by a fresh one with ``classes`` outputs."""
        g = as_rng(rng)
        d = self.params["w2"].shape[0]
        self.params["W"] = g.standard_normal((d, int(classes))) * np.sqrt(1.0 / d)
        self.params["b"] = np.zeros(int(classes))
        return self

    def copy(self):
        return copy.deepcopy(self)

    @staticmethod
    def _images(X):
        X = as_float_array(X, "X", ndim=(3, 4))
        return X[:, None] if X.ndim == 3 else X

    def _features(self, x, training, caches):
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

    def features(self, X):
        """The 'representation' of §11.6: GAP features ``(N, channels[1])`` in evaluation mode."""
        with single_thread():
            return self._features(self._images(X), False, {})

    def scores(self, X, training=False, caches=None):
        """Class scores ``(N, classes)``; ``caches`` (a dict) receives every layer's cache."""
        caches = {} if caches is None else caches
        with single_thread():
            return self._scores(self._images(X), training, caches)

    def _scores(self, x, training, caches):
        h = self._features(x, training, caches)
        out, caches["linear"] = implementation("nn.linear_forward")(h, self.params["W"], self.params["b"])
        return out

    def predict(self, X):
        return np.argmax(self.scores(X), axis=1)

    def accuracy(self, X, y):
        return float(np.mean(self.predict(X) == np.asarray(y)))

    def gradients(self, dscores, caches):
        """Gradients of every learnable parameter from ∂L/∂scores."""
        g = {}
        dh, g["W"], g["b"] = implementation("nn.linear_backward")(dscores, caches["linear"])
        dh = implementation("nn.global_avg_pool_backward")(dh, caches["gap"])
        for i in (2, 1):
            dh = implementation("nn.maxpool2d_backward")(dh, caches[f"pool{i}"])
            dh = implementation("nn.relu_backward")(dh, caches[f"relu{i}"])
            dh, g[f"gamma{i}"], g[f"beta{i}"] = implementation("nn.batchnorm2d_backward")(dh, caches[f"bn{i}"])
            dh, g[f"w{i}"], _ = implementation("nn.conv2d_backward")(dh, caches[f"conv{i}"])
        return g

    # ---------------------------------------------------------------------------------------
    def fit(self, X, y, epochs=10, lr=0.1, batch_size=32, momentum=0.9, weight_decay=5e-4,
            trainable=None, shift=0, rng=None, X_val=None, y_val=None, lr_final=None):
        """Mini-batch SGD with momentum on the mean cross-entropy (+ weight decay).

        Parameters
        ----------
        X : (N, H, W) or (N, C, H, W) array_like
        y : (N,) int array_like
        trainable : iterable of str, optional
            Names of the parameters to update (default all learnable ones): ``("W", "b")``
            trains the head of a frozen feature extractor. Frozen batch norms run in
            evaluation mode (their statistics stay those of the pre-training).
        shift : int
            Random translations of up to ``shift`` pixels (zero fill) as data augmentation.
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
        X = self._images(X)
        y = np.asarray(y, dtype=np.int64)
        epochs = check_int(epochs, "epochs", minimum=0)
        batch_size = check_int(batch_size, "batch_size", minimum=1)
        lr = check_real(lr, "lr", positive=True)
        names = BLOCK1 + BLOCK2 + HEAD if trainable is None else tuple(trainable)
        frozen_features = not any(n in names for n in BLOCK1 + BLOCK2)
        g = as_rng(rng)
        history = {"loss": [], "val": []}
        if lr_final is None:
            rates = [lr] * epochs
        else:
            lr_final = check_real(lr_final, "lr_final", nonnegative=True)
            rates = [lr_final + 0.5 * (lr - lr_final) * (1 + np.cos(np.pi * e / max(epochs - 1, 1)))
                     for e in range(epochs)]
        with single_thread():
            self._fit(X, y, rates, batch_size, momentum, weight_decay, names, frozen_features, shift, g,
                      X_val, y_val, history)
        return history

    def _fit(self, X, y, rates, batch_size, momentum, weight_decay, names, frozen_features, shift, g,
             X_val, y_val, history):
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
                caches = {}
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
                predicted = np.argmax(self._scores(self._images(X_val), False, {}), axis=1)
                history["val"].append(float(np.mean(predicted == np.asarray(y_val))))
        history["seconds"] = time.perf_counter() - start


def _random_shift(x: np.ndarray, shift: int, g: np.random.Generator) -> np.ndarray:
    """Each image translated by (dy, dx) ∈ [−shift, shift]², zero fill."""
    n, c, h, w = x.shape
    padded = np.pad(x, ((0, 0), (0, 0), (shift, shift), (shift, shift)))
    dy = g.integers(0, 2 * shift + 1, n)
    dx = g.integers(0, 2 * shift + 1, n)
    rows = dy[:, None] + np.arange(h)[None, :]
    cols = dx[:, None] + np.arange(w)[None, :]
    return padded[np.arange(n)[:, None, None, None], np.arange(c)[None, :, None, None],
                  rows[:, None, :, None], cols[:, None, None, :]]
