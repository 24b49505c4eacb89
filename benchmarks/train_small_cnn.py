#!/usr/bin/env python
"""Chapters 10–11 benchmark: a small CNN trained with cvkit's NumPy layers on the 8×8 digits,
and the transfer-learning experiment of §11.6 at a larger scale than the notebook can afford.

    .venv/bin/python benchmarks/train_small_cnn.py            # full run (about a minute)
    .venv/bin/python benchmarks/train_small_cnn.py --quick    # fewer repetitions of the transfer table
    .venv/bin/python benchmarks/train_small_cnn.py --check    # exit status 1 if the target is missed

Target (issue 9): ``conv3×3(16)–BN–ReLU–maxpool2 – conv3×3(32)–BN–ReLU–maxpool2 – GAP – linear``
(``cvkit.nn.SmallCNN``) trained on the 1258 training digits (``cvkit.data.digits``) reaches a
test accuracy ≥ 0.97 on the 539 test digits in under 2 minutes on 2 cores. Training: SGD with
momentum 0.9, batch 32, weight decay 5e-4, 15 epochs, learning rate decaying from 0.05 to
0.0005 (cosine), BLAS on one thread (``threadpoolctl``); seeds fixed, so the accuracy is reproducible (the time is
not: it depends on the machine's load).

Transfer learning (§11.6): a SmallCNN(16, 32) pre-trained on the digits 0–4 (15 epochs) is
reused for 5–9 with k labelled images per class: (a) frozen features + a new linear head
(60 epochs, lr 0.1), (b) fine-tuned: the whole network from the pre-trained weights (60 epochs,
lr 0.05), (c) the same network trained from scratch with the same recipe; accuracy on the 269
test images of 5–9, mean ± std over repetitions with different training subsets.
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from cvkit import data, nn  # noqa: E402

TARGET_ACCURACY = 0.97
TARGET_SECONDS = 120.0


def train_full(epochs: int = 15, channels=(16, 32)):
    (X_train, y_train), (X_test, y_test) = data.digits(flatten=False)
    model = nn.SmallCNN(10, channels=channels, rng=0)
    start = time.perf_counter()
    history = model.fit(X_train, y_train, epochs=epochs, lr=0.05, batch_size=32, momentum=0.9,
                        weight_decay=5e-4, rng=1, lr_final=0.0005)
    seconds = time.perf_counter() - start
    return model.accuracy(X_test, y_test), seconds, history


def transfer_table(shots=(1, 3, 10, 30), repeats=5, channels=(16, 32), pre_epochs=15):
    (X_train, y_train), (X_test, y_test) = data.digits(flatten=False)
    source = y_train < 5
    pre = nn.SmallCNN(5, channels=channels, rng=0)
    start = time.perf_counter()
    pre.fit(X_train[source], y_train[source], epochs=pre_epochs, lr=0.05, batch_size=32, rng=1, lr_final=0.0005)
    pre_seconds = time.perf_counter() - start
    pre_accuracy = pre.accuracy(X_test[y_test < 5], y_test[y_test < 5])
    X_eval, y_eval = X_test[y_test >= 5], y_test[y_test >= 5] - 5
    rows = []
    for k in shots:
        results = {"frozen features": [], "fine-tuned": [], "from scratch": []}
        for rep in range(repeats):
            rng = np.random.default_rng(100 + rep)
            idx = np.concatenate([rng.choice(np.flatnonzero(y_train == c), k, replace=False) for c in range(5, 10)])
            X_few, y_few = X_train[idx], y_train[idx] - 5
            batch = min(10, len(idx))
            frozen = pre.copy().new_head(5, rng=rep)
            frozen.fit(X_few, y_few, epochs=60, lr=0.1, batch_size=batch, trainable=("W", "b"), rng=rep)
            results["frozen features"].append(frozen.accuracy(X_eval, y_eval))
            tuned = pre.copy().new_head(5, rng=rep)
            tuned.fit(X_few, y_few, epochs=60, lr=0.05, batch_size=batch, rng=rep)
            results["fine-tuned"].append(tuned.accuracy(X_eval, y_eval))
            scratch = nn.SmallCNN(5, channels=channels, rng=1000 + rep)
            scratch.fit(X_few, y_few, epochs=60, lr=0.05, batch_size=batch, rng=rep)
            results["from scratch"].append(scratch.accuracy(X_eval, y_eval))
        rows.append((k, {name: (float(np.mean(v)), float(np.std(v))) for name, v in results.items()}))
    return pre_accuracy, pre_seconds, rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 repetitions per row of the transfer table")
    parser.add_argument("--check", action="store_true", help="exit status 1 if the target is missed")
    parser.add_argument("--no-transfer", action="store_true", help="only the 10-class training run")
    args = parser.parse_args(argv)
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, NumPy {np.__version__}, "
          f"BLAS limited to 1 thread during training")

    accuracy, seconds, history = train_full()
    met = accuracy >= TARGET_ACCURACY and seconds < TARGET_SECONDS
    print("\nSmallCNN(16, 32) on all digits, 15 epochs")
    print(f"  test accuracy {accuracy:.4f} (target >= {TARGET_ACCURACY}), training time {seconds:.1f} s "
          f"(target < {TARGET_SECONDS:.0f} s), {seconds / len(history['loss']):.2f} s per epoch -> "
          f"{'met' if met else 'NOT MET'}")
    print("  mean training loss per epoch: " + " ".join(f"{v:.3f}" for v in history["loss"]))

    if not args.no_transfer:
        repeats = 2 if args.quick else 5
        pre_accuracy, pre_seconds, rows = transfer_table(repeats=repeats)
        print(f"\ntransfer 0-4 -> 5-9: pre-trained SmallCNN(16, 32), 15 epochs on 0-4 "
              f"({pre_seconds:.1f} s, test accuracy on 0-4 {pre_accuracy:.3f}); accuracy on the 5-9 test set, "
              f"mean ± std over {repeats} training subsets")
        names = list(rows[0][1])
        print(f"  {'images/class':>12} " + " ".join(f"{n:>18}" for n in names))
        for k, results in rows:
            print(f"  {k:>12} " + " ".join(f"{results[n][0]:>11.3f} ± {results[n][1]:.3f}" for n in names))
    return 1 if (args.check and not met) else 0


if __name__ == "__main__":
    sys.exit(main())
