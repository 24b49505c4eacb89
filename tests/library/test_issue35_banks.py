"""The mistakes issue #35 (item 4) found unnamed, written as a student would write them, are
named with their own name and fix; a failure no mistake of the bank explains is marked
``unexplained`` in the report's data (for course-level tools to count).
"""
from __future__ import annotations

import math

import numpy as np

from cvkit.grading import evaluate


def batchnorm_updated_then_used(x, gamma, beta, running_mean, running_var, training, momentum=0.1, eps=1e-5):
    x = np.asarray(x, dtype=np.float64)
    gamma, beta = np.asarray(gamma, dtype=np.float64), np.asarray(beta, dtype=np.float64)
    rm, rv = np.asarray(running_mean, dtype=np.float64), np.asarray(running_var, dtype=np.float64)
    if training:
        n = x.shape[0] * x.shape[2] * x.shape[3]
        rm = (1 - momentum) * rm + momentum * x.mean(axis=(0, 2, 3))
        rv = (1 - momentum) * rv + momentum * x.var(axis=(0, 2, 3)) * n / (n - 1)
    # the running statistics just updated are used on this batch as well
    out = gamma[None, :, None, None] * (x - rm[None, :, None, None]) / np.sqrt(rv[None, :, None, None] + eps) \
        + beta[None, :, None, None]
    cache = {"x": x, "gamma": gamma, "beta": beta, "running_mean": rm, "running_var": rv,
             "training": bool(training), "momentum": momentum, "eps": eps}
    return out, cache


def hough_with_degrees(edges, theta_step=math.pi / 180, rho_step=1.0):
    e = np.asarray(edges)
    rows, cols = np.nonzero(e)
    count = int(math.floor(math.pi / theta_step + 1e-9))
    thetas = -math.pi / 2 + np.arange(count) * theta_step
    k = math.ceil(math.hypot(*e.shape) / rho_step - 1e-9)
    rhos = np.arange(-k, k + 1) * rho_step
    acc = np.zeros((rhos.size, thetas.size), dtype=np.int64)
    for j, theta in enumerate(thetas):
        degrees = theta * 180 / math.pi
        rho = cols * np.cos(degrees) + rows * np.sin(degrees)   # cos/sin of degrees
        index = np.floor(rho / rho_step + 0.5).astype(int) + k
        index = index[(index >= 0) & (index < rhos.size)]
        np.add.at(acc[:, j], index, 1)
    return acc, thetas, rhos


def warmup_floor(step, warmup_steps, lr_target, lr_start=0.0):
    if warmup_steps == 0:
        return lr_target + 0.0 * np.asarray(step, dtype=float) if np.ndim(step) else float(lr_target)
    t = np.minimum(np.asarray(step), warmup_steps)
    value = lr_start + (lr_target - lr_start) * (t // warmup_steps)
    return float(value) if np.ndim(value) == 0 else value


def test_batchnorm_with_the_updated_running_statistics_is_named():
    report = evaluate("nn.batchnorm2d_forward", batchnorm_updated_then_used)
    assert not report.passed
    assert report.mistake == "updated running statistics used to normalise in training"
    assert "batch's mean" in report.hint


def test_hough_votes_with_degrees_in_cos_sin_are_named():
    report = evaluate("detection.hough_lines", hough_with_degrees)
    assert not report.passed
    assert report.mistake == "θ in degrees inside np.cos/np.sin", report.text()


def test_warmup_with_floor_division_is_named():
    report = evaluate("train.warmup", warmup_floor)
    assert not report.passed
    assert report.mistake.startswith("integer division (//)")
    assert "true division" in report.hint


def test_a_failure_no_mistake_explains_is_marked_unexplained():
    def off(ix, iy, norm="l2"):  # a wrong answer the bank does not know
        return np.hypot(ix, iy) + 0.5

    report = evaluate("edges.magnitude", off)
    assert not report.passed and report.mistake is None
    assert all(c.unexplained for c in report.cases)
    assert all(c["unexplained"] for c in report.to_dict()["cases"])


def test_a_named_mistake_a_pass_and_the_stub_are_not_unexplained():
    def l2_squared(ix, iy, norm="l2"):
        ix, iy = np.asarray(ix, dtype=float), np.asarray(iy, dtype=float)
        return {"l2": ix * ix + iy * iy, "l1": np.abs(ix) + np.abs(iy)}.get(norm, np.maximum(np.abs(ix), np.abs(iy)))

    named = evaluate("edges.magnitude", l2_squared)
    assert named.mistake == "L2 without the square root"
    assert not any(c.unexplained for c in named.cases)

    def stub(ix, iy, norm="l2"):
        raise NotImplementedError

    assert not any(c.unexplained for c in evaluate("edges.magnitude", stub).cases)
    assert not any(c.unexplained for c in evaluate("edges.magnitude", lambda ix, iy, norm="l2": np.hypot(ix, iy)
                                                  if norm == "l2" else (np.abs(ix) + np.abs(iy) if norm == "l1"
                                                                        else np.maximum(np.abs(ix), np.abs(iy)))).cases)
