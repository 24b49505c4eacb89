#!/usr/bin/env python
"""Chapters 9–10 benchmark: cvkit.learn against scikit-learn (targets) and OpenCV (informative).

    .venv/bin/python benchmarks/bench_ch09.py            # 5 repeats per timing
    .venv/bin/python benchmarks/bench_ch09.py --quick    # 2 repeats
    .venv/bin/python benchmarks/bench_ch09.py --check    # exit status 1 if a target is missed

Target (issue 8): k-means with k = 100 on 20000 × 128 float64 samples in at most 3× the time of
``sklearn.cluster.KMeans(n_clusters=100, n_init=1)`` (scikit-learn's defaults otherwise:
greedy k-means++, Lloyd, ``max_iter=300``, ``tol=1e-4``; cvkit's defaults: greedy k-means++,
at most 50 Lloyd iterations, stopping at a fixed point), with a mean inertia (over one
run per seed, at least 8 seeds: a single run varies by a few percent with its seeding) within
1 % of scikit-learn's. Two data sets: Gaussian noise (no structure: both run their maximum of
iterations or close to it) and 100 Gaussian clusters (``make_blobs``, both converge early).

Informative rows: 1-NN on the 8×8 digits against ``KNeighborsClassifier(algorithm="brute")``,
mini-batch SGD of a softmax classifier on the digits against ``SGDClassifier(loss="log_loss")``
(not the same algorithm: one-vs-rest, its own learning-rate schedule), ``cv2.kmeans``.

Times are the median of the repeats (after one warm-up call), in milliseconds; ratio is
cvkit / peer.
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import sklearn
from sklearn.cluster import KMeans
from sklearn.datasets import make_blobs
from sklearn.linear_model import SGDClassifier
from sklearn.neighbors import KNeighborsClassifier

from cvkit import data
from cvkit.learn import kmeans, knn_predict, linear_scores, sgd_train

try:
    import cv2
except ImportError:  # OpenCV is a test-only dependency
    cv2 = None

INERTIA_TOLERANCE = 0.01


def timeit(fn, repeats: int) -> tuple[float, object]:
    """Median wall time of ``repeats`` calls in ms (after one warm-up call), and the last result."""
    result = fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times), result


@dataclass
class Row:
    operation: str
    ours_ms: float
    peer: str
    peer_ms: float
    target: float | None  # maximal ratio, None = informative
    note: str = ""

    @property
    def ratio(self) -> float:
        return self.ours_ms / self.peer_ms

    @property
    def verdict(self) -> str:
        if self.target is None:
            return "info"
        return "ok" if self.ratio <= self.target else "MISSED"


def inertia(X, centers, labels) -> float:
    return float(np.sum((X - centers[labels]) ** 2))


def _runs(fit, count: int) -> tuple[float, list]:
    """``count`` calls ``fit(seed)`` with seeds 0, 1, ...: the median time in ms of all but the
    first (warm-up) call, and every result."""
    results, times = [], []
    for seed in range(count):
        start = time.perf_counter()
        results.append(fit(seed))
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times[1:]), results


def kmeans_rows(repeats: int) -> tuple[list[Row], list[str]]:
    rows, missed = [], []
    datasets = {
        "k-means k=100 noise": np.random.default_rng(0).standard_normal((20000, 128)),
        "k-means k=100 blobs": make_blobs(20000, 128, centers=100, cluster_std=2.0, random_state=0)[0],
    }
    count = max(8, repeats + 1)  # one run per seed: the inertia of one run varies by a few % with the seeding
    for name, X in datasets.items():
        ours_ms, ours = _runs(lambda seed: kmeans(X, 100, rng=seed), count)
        peer_ms, models = _runs(lambda seed: KMeans(n_clusters=100, n_init=1, random_state=seed).fit(X), count)
        quality = np.mean([inertia(X, c, lab) for c, lab in ours]) / np.mean([m.inertia_ for m in models])
        note = (f"mean inertia over {count} seeds: {quality:.4f}x sklearn's; "
                f"sklearn iterations {min(m.n_iter_ for m in models)}-{max(m.n_iter_ for m in models)}")
        rows.append(Row(name, ours_ms, "sklearn KMeans(n_init=1)", peer_ms, 3.0, note))
        if quality > 1 + INERTIA_TOLERANCE:
            missed.append(f"{name}: inertia {quality:.4f}x scikit-learn's (target <= {1 + INERTIA_TOLERANCE})")
        if cv2 is not None:
            X32 = X.astype(np.float32)
            criteria = (cv2.TERM_CRITERIA_MAX_ITER + cv2.TERM_CRITERIA_EPS, 50, 1e-4)
            cv_ms, _ = timeit(lambda: cv2.kmeans(X32, 100, None, criteria, 1, cv2.KMEANS_PP_CENTERS), max(1, repeats // 2))
            rows.append(Row(name, ours_ms, "cv2.kmeans (float32, 50 it.)", cv_ms, None))
    return rows, missed


def digits_rows(repeats: int) -> list[Row]:
    (X_train, y_train), (X_test, y_test) = data.digits()
    rows = []
    ours_ms, pred = timeit(lambda: knn_predict(X_train, y_train, X_test, 1), repeats)
    knn = KNeighborsClassifier(1, algorithm="brute")
    peer_ms, theirs = timeit(lambda: knn.fit(X_train, y_train).predict(X_test), repeats)
    rows.append(Row("1-NN digits", ours_ms, "KNeighborsClassifier brute", peer_ms, None,
                    f"accuracy {np.mean(pred == y_test):.3f} vs {np.mean(theirs == y_test):.3f}"))

    ours_ms, (W, b, _) = timeit(lambda: sgd_train(X_train, y_train, 10, 0.5, 30, 32, reg=1e-4, rng=0), repeats)
    acc = np.mean(linear_scores(X_test, W, b).argmax(axis=1) == y_test)
    clf = SGDClassifier(loss="log_loss", alpha=1e-4, max_iter=30, tol=None, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        peer_ms, model = timeit(lambda: clf.fit(X_train, y_train), repeats)
    rows.append(Row("SGD softmax digits", ours_ms, "SGDClassifier log_loss 30 ep.", peer_ms, None,
                    f"accuracy {acc:.3f} vs {model.score(X_test, y_test):.3f}"))
    return rows


def machine_line() -> str:
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    parts = [
        f"CPUs {os.cpu_count()} (usable {usable})",
        platform.processor() or platform.machine(),
        f"Python {platform.python_version()}",
        f"numpy {np.__version__}",
        f"scikit-learn {sklearn.__version__}",
        f"opencv {cv2.__version__}" if cv2 is not None else "opencv not installed",
    ]
    return "machine: " + ", ".join(parts)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="2 repeats")
    parser.add_argument("--repeats", type=int, default=None, help="timing repeats (default 5, or 2 with --quick)")
    parser.add_argument("--check", action="store_true", help="exit with status 1 if a target is missed")
    args = parser.parse_args(argv)
    repeats = args.repeats or (2 if args.quick else 5)
    print(machine_line())
    print(f"{repeats} repeats (median)\n")
    rows, missed = kmeans_rows(repeats)
    rows += digits_rows(repeats)
    header = f"{'operation':<21} {'cvkit ms':>9}  {'peer':<32} {'peer ms':>9} {'ratio':>7}  {'target':<8} {'':<6} note"
    print(header)
    print("-" * len(header))
    for row in rows:
        target = f"<= {row.target:g}x" if row.target else "info"
        print(f"{row.operation:<21} {row.ours_ms:>9.1f}  {row.peer:<32} {row.peer_ms:>9.1f} {row.ratio:>6.2f}x  "
              f"{target:<8} {row.verdict:<6} {row.note}")
    missed += [f"{r.operation}: {r.ratio:.2f}x (target <= {r.target:g}x)" for r in rows if r.verdict == "MISSED"]
    if missed:
        print("\nMISSED: " + "; ".join(missed) + " (timings are noisy on a loaded machine: rerun to confirm)")
    return 1 if (missed and args.check) else 0


if __name__ == "__main__":
    sys.exit(main())
