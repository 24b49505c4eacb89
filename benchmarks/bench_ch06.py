#!/usr/bin/env python
"""Chapter 6 benchmark: cvkit's detectors against scikit-image (targets) and OpenCV
(informative), float64, plus the GHT's detection rate on generated scenes.

    .venv/bin/python benchmarks/bench_ch06.py            # 7 repeats per timing
    .venv/bin/python benchmarks/bench_ch06.py --quick    # 3 repeats
    .venv/bin/python benchmarks/bench_ch06.py --check    # exit status 1 if a target is missed

Times are the median of the repeats (after one warm-up call), in milliseconds; ratio is
cvkit / peer. Targets (issue 5): ZNCC of a 64×64 template over a 512×512 image ≤ 2×
``skimage.feature.match_template`` (same output: pad_input=False); Hough lines ≤ 3×
``skimage.transform.hough_line`` on the Canny edges of the camera image (same θ sampling: 180
angles in [−π/2, π/2), ρ step 1). The other rows are informative: OpenCV's matchTemplate
works in float32 (the image is converted, conversion included), SAD has no library peer, and
``cv2.HoughLines`` returns lines, not the accumulator.
"""
from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE)]  # cvkit and _timing from this checkout, however started

import skimage
from skimage import feature
from skimage import transform as sktransform

from cvkit import data, detection, edges

from _timing import BenchmarkParser, Row, Targets, comparison_table, machine_line, optional_import, timeit

cv2 = optional_import("cv2")  # OpenCV is a test-only dependency


def timing_rows(repeats: int) -> list[Row]:
    rows: list[Row] = []
    t = lambda fn: timeit(fn, repeats)  # noqa: E731
    image = data.camera()                                  # 512 x 512 float64
    tpl = image[200:264, 240:304].copy()                   # 64 x 64
    ours = t(lambda: detection.match_template(image, tpl, "zncc"))
    rows.append(Row("zncc 64×64 over 512×512", ours, "skimage.feature.match_template",
                    t(lambda: feature.match_template(image, tpl)), 2.0))
    if cv2 is not None:
        rows.append(Row("zncc 64×64 over 512×512", ours, "cv2.matchTemplate TM_CCOEFF_NORMED (float32)",
                        t(lambda: cv2.matchTemplate(image.astype(np.float32), tpl.astype(np.float32),
                                                    cv2.TM_CCOEFF_NORMED)), None))
        rows.append(Row("ssd 64×64 over 512×512", t(lambda: detection.match_template(image, tpl, "ssd")),
                        "cv2.matchTemplate TM_SQDIFF (float32)",
                        t(lambda: cv2.matchTemplate(image.astype(np.float32), tpl.astype(np.float32),
                                                    cv2.TM_SQDIFF)), None))
    small = tpl[:16, :16].copy()
    rows.append(Row("zncc 16×16 over 512×512", t(lambda: detection.match_template(image, small)),
                    "skimage.feature.match_template", t(lambda: feature.match_template(image, small)), None))

    edge_map = edges.canny(image, 2.0)
    ours = t(lambda: detection.hough_lines(edge_map))
    rows.append(Row(f"hough lines ({int(edge_map.sum())} edge px, 180 θ)", ours, "skimage.transform.hough_line",
                    t(lambda: sktransform.hough_line(edge_map)), 3.0))
    acc, thetas, rhos = detection.hough_lines(edge_map)
    rows.append(Row("hough peaks (10, min_distance 9)",
                    t(lambda: detection.hough_peaks(acc, thetas, rhos, 10, None, 9)),
                    "skimage.transform.hough_line_peaks",
                    t(lambda: sktransform.hough_line_peaks(acc, thetas, rhos, 9, 9, None, 10)), None))
    if cv2 is not None:
        u8 = edge_map.astype(np.uint8) * 255
        rows.append(Row(f"hough lines ({int(edge_map.sum())} edge px, 180 θ)", ours,
                        "cv2.HoughLines (lines only, uint8)",
                        t(lambda: cv2.HoughLines(u8, 1, math.pi / 180, 150)), None))
    return rows


def ght_rate(scenes: int = 10) -> tuple[int, float]:
    """Issue target: found within 2 px, one scale and one angle step, in >= 9 of 10 scenes."""
    size = 40
    tpl, _ = data.part_template(size)
    table = detection.ght_build(edges.canny(tpl, 1.0), tpl, bins=36)
    scales = np.round(np.arange(0.8, 1.2001, 0.1), 3)
    angles = np.deg2rad(np.arange(-180, 180, 10))
    found, elapsed = 0, []
    for seed in range(scenes):
        rng = np.random.default_rng(1000 + seed)
        s, a = float(rng.uniform(0.8, 1.2)), float(rng.uniform(-math.pi, math.pi))
        scene, pose = data.part_scene((112, 112), scale=s, angle=a, size=size, clutter=6, occlusion=0.3, rng=rng)
        start = time.perf_counter()
        _, (x, y, s_hat, a_hat) = detection.ght_detect(scene, table, scales, angles, edge_params={"sigma": 1.0})
        elapsed.append(time.perf_counter() - start)
        tx, ty = data.to_scene(pose, table["reference"])
        da = abs((a_hat - a + math.pi) % (2 * math.pi) - math.pi)
        found += math.hypot(x - tx, y - ty) <= 2 and abs(s_hat - s) <= 0.1 + 1e-9 and da <= math.radians(10) + 1e-9
    return found, 1e3 * statistics.median(elapsed)


def main(argv=None) -> int:
    args = BenchmarkParser(__doc__, repeats=7, quick_repeats=3).parse_args(argv)
    repeats = args.repeats
    print(machine_line(skimage, opencv=cv2))
    print(f"{repeats} repeats (median)\n")
    rows = timing_rows(repeats)
    comparison_table(rows, digits=2)
    targets = Targets()
    targets.check_rows(rows)
    found, ms = ght_rate()
    print(f"\nGHT, 5 scales × 36 angles on 112×112 scenes with clutter and 30% occlusion: found in {found} / 10 "
          f"(target >= 9), median {ms:.0f} ms per scene")
    targets.check("GHT detection rate", found >= 9)
    return targets.finish(args.check)


if __name__ == "__main__":
    sys.exit(main())
