#!/usr/bin/env python
"""Chapter 12's recipe table: what each step of a training recipe is worth on the digits.

    .venv/bin/python benchmarks/recipe_table.py             # 5 seeds, 30 epochs (~1 min CPU, 3 min on a busy 2-core machine)
    .venv/bin/python benchmarks/recipe_table.py --quick     # 2 seeds, 10 epochs
    .venv/bin/python benchmarks/recipe_table.py --seeds 10 --output /tmp/table.md
    .venv/bin/python benchmarks/recipe_table.py --check     # exit 1 if the notebook quotes another table

The network is the chapter's teaching model (``cvkit.train._models``: 64-256-10 ReLU MLP,
plain mini-batch SGD, batch 32) trained on ``cvkit.data.digits()`` (1258 training, 539 test
images). First the learning rate is chosen by a sweep on a validation split of the training
set (20 %, never the test set); the table then uses ``net.TUNED_LR`` and says whether the
sweep agrees. Every row adds one step to the recipe (the augmentations are tried alone and
not carried forward, see ``net.RECIPE_STEPS``) and is trained from the same seeds, so the
change of a row is reported as the mean ± std of its per-seed differences. The Markdown table
printed at the end is the one quoted in ``lectures/ch12_training/ch12_training.ipynb``.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from cvkit import data  # noqa: E402
from cvkit.train import _models as net  # noqa: E402

SWEEP = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0)
NOTEBOOK = Path(__file__).resolve().parents[1] / "lectures" / "ch12_training" / "ch12_training.ipynb"


def lr_sweep(train_set, val_set, epochs: int, seeds) -> tuple[float, dict]:
    """Validation accuracy of a constant-rate network for each rate of :data:`SWEEP`."""
    (X_fit, y_fit), (X_val, y_val) = train_set, val_set
    scores = {}
    for lr in SWEEP:
        accs = [net.accuracy(net.train(X_fit, y_fit, net.BASELINE.but(lr=lr, epochs=epochs), rng=s).params, X_val, y_val)
                for s in seeds]
        scores[lr] = float(np.mean(accs))
    return max(scores, key=scores.get), scores


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=None, help="number of seeds per row (default 5, 2 with --quick)")
    parser.add_argument("--epochs", type=int, default=None, help="epochs of the baseline (default 30, 10 with --quick)")
    parser.add_argument("--quick", action="store_true", help="2 seeds and 10 epochs")
    parser.add_argument("--output", type=Path, default=None, help="also write the Markdown table to this file")
    parser.add_argument("--check", action="store_true",
                        help="exit with status 1 unless the chapter notebook quotes exactly this table")
    args = parser.parse_args(argv)
    seeds = tuple(range(args.seeds if args.seeds is not None else (2 if args.quick else 5)))
    epochs = args.epochs if args.epochs is not None else (10 if args.quick else net.BASELINE.epochs)

    print(f"# machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"Python {platform.python_version()}, NumPy {np.__version__}")
    (X_train, y_train), (X_test, y_test) = data.digits()
    fit, val = net.split_validation(X_train, y_train)

    start = time.perf_counter()
    chosen, scores = lr_sweep(fit, val, epochs, seeds[:3])
    print("# learning-rate sweep (validation accuracy, constant rate, "
          f"{epochs} epochs, {min(3, len(seeds))} seeds): "
          + ", ".join(f"{lr:g}: {100 * acc:.2f} %" for lr, acc in scores.items()))
    agree = "agrees with" if chosen == net.TUNED_LR else "DIFFERS from"
    print(f"# chosen lr = {chosen:g}, which {agree} net.TUNED_LR = {net.TUNED_LR:g} used by the table "
          f"({time.perf_counter() - start:.0f} s)")

    total = sum(members for _, _, members, _ in net.RECIPE_STEPS) * len(seeds)
    done = [0]

    def progress():
        done[0] += 1
        print(f"\r# training network {done[0]}/{total}", end="", file=sys.stderr, flush=True)

    start = time.perf_counter()
    rows = net.recipe_table((X_train, y_train), (X_test, y_test), seeds=seeds, epochs=epochs, progress=progress)
    elapsed = time.perf_counter() - start
    print(file=sys.stderr)
    table = net.format_recipe_table(rows)
    print(f"# recipe table: {len(seeds)} seeds, {epochs} epochs, {total} networks in {elapsed:.0f} s\n")
    print(table)
    if args.output is not None:
        args.output.write_text(table + "\n")
    if args.check:
        import json

        notebook = json.loads(NOTEBOOK.read_text())
        prose = "\n".join("".join(c["source"]) for c in notebook["cells"] if c["cell_type"] == "markdown")
        if table not in prose:
            print(f"\n# the table in {NOTEBOOK.name} differs from this run: update the notebook's prose")
            return 1
        print(f"\n# {NOTEBOOK.name} quotes exactly this table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
