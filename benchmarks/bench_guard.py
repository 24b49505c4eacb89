"""What the grader's guard costs: references run plainly and under the guard, on their hidden cases.

    python benchmarks/bench_guard.py [--seeds 3] [--repeats 3]

A candidate is graded under :func:`cvkit.grading.runtime.guard.run_guarded`: on copies of its
inputs, with a time limit, and with a ``sys.setprofile`` watch that records calls into
forbidden code (the reference implementations, scipy.ndimage, OpenCV...). The watch sees every
call and return of the candidate and of the libraries it uses, so Python-heavy code pays most.
This prints, per algorithm, the CPU seconds of its reference over the hidden cases of
``--seeds`` seeds, called plainly and under the guard as grading calls it (the check's
forbidden libraries and functions, the reference watch on), the best of ``--repeats`` runs,
and the ratio guarded / plain.
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from cvkit import registry  # noqa: E402
from cvkit.grading.runtime.guard import run_guarded  # noqa: E402

ALGORITHMS = ("calibration.calibrate", "features.sift", "learn.sgd_train", "edges.canny", "filters.bilateral")


def _cpu(run) -> float:
    start = time.process_time()
    run()
    return time.process_time() - start


def measure(algorithm_id: str, seeds: int, repeats: int) -> tuple[float, float]:
    """(plain, guarded) CPU seconds of the reference over the hidden cases of ``seeds`` seeds."""
    record = registry.get(algorithm_id)
    spec = record.check
    cases = [case for seed in range(seeds) for case in spec.hidden_cases(np.random.default_rng(seed))]
    reference = record.reference

    def plain():
        for case in cases:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                try:
                    reference(*case.args, **case.kwargs)
                except Exception:  # noqa: BLE001 - a refused case costs the same either way
                    pass

    def guarded():
        for case in cases:
            run_guarded(reference, case.args, case.kwargs, time_limit=spec.time_limit,
                        forbidden_libraries=spec.forbidden_libraries, forbidden_functions=spec.forbidden,
                        allowed_ids=tuple(spec.allowed) + (algorithm_id,), watch_reference=True)

    plain()  # warm-up: imports and caches
    guarded()
    return (min(_cpu(plain) for _ in range(repeats)), min(_cpu(guarded) for _ in range(repeats)))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    print(f"{'algorithm':28s} {'plain s':>8s} {'guarded s':>10s} {'ratio':>6s}")
    for algorithm_id in ALGORITHMS:
        plain, guarded = measure(algorithm_id, args.seeds, args.repeats)
        print(f"{algorithm_id:28s} {plain:8.3f} {guarded:10.3f} {guarded / plain:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
