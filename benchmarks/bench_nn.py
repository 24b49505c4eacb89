#!/usr/bin/env python
"""Chapters 10–11 benchmark: cvkit's NumPy layers against a SciPy peer (informative rows).

    .venv/bin/python benchmarks/bench_nn.py            # 7 repeats per timing
    .venv/bin/python benchmarks/bench_nn.py --quick    # 3 repeats

Times are the median of the repeats after one warm-up call, in milliseconds, BLAS limited to
one thread. The batch is 32 feature maps of 16 channels at 16×16 (3×3 convolution to 32
channels, padding 1), the size of the small CNNs of the notebooks scaled up. The peer of the
convolution is the oracle of the tests: for each image and filter, the sum over the input
channels of ``scipy.signal.correlate(x_c, w_fc, mode="valid")`` on the padded input. The issue
sets no timing target for the layers (its target — a small CNN trained to ≥ 0.97 on the digits
in under 2 minutes — is measured by ``train_small_cnn.py``); these rows document the cost.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy.signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from cvkit import nn  # noqa: E402
from cvkit.nn._model import single_thread  # noqa: E402


def timeit(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def scipy_conv(x, w, b, padding):
    xp = np.pad(x, ((0, 0), (0, 0), (padding, padding), (padding, padding)))
    return np.array([[sum(scipy.signal.correlate(xp[n, c], w[f, c], mode="valid") for c in range(x.shape[1])) + b[f]
                      for f in range(w.shape[0])] for n in range(x.shape[0])])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    repeats = 3 if args.quick else 7
    rng = np.random.default_rng(0)
    x = rng.normal(size=(32, 16, 16, 16))
    w, b = rng.normal(size=(32, 16, 3, 3)), rng.normal(size=32)
    rows = []
    with single_thread():
        out, cache = nn.conv2d_forward(x, w, b, padding=1)
        dout = rng.normal(size=out.shape)
        rows.append(("conv2d_forward 3×3, 16→32", timeit(lambda: nn.conv2d_forward(x, w, b, padding=1), repeats),
                     "scipy.signal.correlate, per channel", timeit(lambda: scipy_conv(x, w, b, 1), max(1, repeats // 3))))
        rows.append(("conv2d_backward", timeit(lambda: nn.conv2d_backward(dout, cache), repeats), "", None))
        h, pcache = nn.maxpool2d_forward(out)
        rows.append(("maxpool2d_forward 2×2/2", timeit(lambda: nn.maxpool2d_forward(out), repeats), "", None))
        rows.append(("maxpool2d_backward", timeit(lambda: nn.maxpool2d_backward(np.ones_like(h), pcache), repeats), "", None))
        bn_args = (out, np.ones(32), np.zeros(32), np.zeros(32), np.ones(32), True)
        _, bcache = nn.batchnorm2d_forward(*bn_args)
        rows.append(("batchnorm2d_forward", timeit(lambda: nn.batchnorm2d_forward(*bn_args), repeats), "", None))
        rows.append(("batchnorm2d_backward", timeit(lambda: nn.batchnorm2d_backward(dout, bcache), repeats), "", None))
    print(f"NumPy {np.__version__}, SciPy {scipy.__version__}; batch (32, 16, 16, 16), median of {repeats}\n")
    print(f"{'operation':28} {'cvkit ms':>9}  {'peer':36} {'peer ms':>8} {'ratio':>6}")
    for name, ours, peer, peer_ms in rows:
        tail = f"{peer:36} {peer_ms:8.1f} {ours / peer_ms:6.2f}" if peer_ms else ""
        print(f"{name:28} {ours:9.2f}  {tail}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
