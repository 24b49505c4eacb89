"""Chapter 12 (cvkit.train) against oracles: PyTorch's schedulers re-derived from their
chainable (step-by-step) forms and from OneCycleLR's phase table, OpenCV / scikit-image for
the bilinear resize of the random resized crop, SciPy's distributions for the random draws
(Kolmogorov–Smirnov and chi-square tests), brute-force definitions elsewhere; then bad input
(hypothesis) and the private teaching model of the chapter.

PyTorch is not a dependency: its schedulers are re-implemented here from their published
update rules, independently of cvkit's closed forms.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats as stats
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cvkit
from cvkit import registry, train
from cvkit.train import _augment, _models

cv2 = pytest.importorskip("cv2")
FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# --------------------------------------------------------------------------------------------
# schedules vs PyTorch's update rules
# --------------------------------------------------------------------------------------------
def torch_step_lr(lr0, step_size, gamma, epochs):
    """torch.optim.lr_scheduler.StepLR, chainable form: multiply by gamma at every multiple of step_size."""
    lrs = [lr0]
    for epoch in range(1, epochs):
        lrs.append(lrs[-1] * gamma if epoch % step_size == 0 else lrs[-1])
    return np.array(lrs)


def torch_cosine_annealing(lr0, T_max, eta_min):
    """torch.optim.lr_scheduler.CosineAnnealingLR, chainable (recursive) form for epochs 0..T_max."""
    lrs = [lr0]
    for t in range(1, T_max + 1):
        factor = (1 + math.cos(math.pi * t / T_max)) / (1 + math.cos(math.pi * (t - 1) / T_max))
        lrs.append(eta_min + (lrs[-1] - eta_min) * factor)
    return np.array(lrs)


def torch_linear_lr(lr_target, start_factor, total_iters, steps):
    """torch.optim.lr_scheduler.LinearLR(start_factor, end_factor=1), chainable form."""
    lrs = [lr_target * start_factor]
    for t in range(1, steps):
        if t > total_iters:
            lrs.append(lrs[-1])
        else:
            lrs.append(lrs[-1] * (1.0 + (1.0 - start_factor) / (total_iters * start_factor + (t - 1) * (1.0 - start_factor))))
    return np.array(lrs)


class TorchOneCycle:
    """torch.optim.lr_scheduler.OneCycleLR(three_phase=False, anneal_strategy='cos'): the
    scheduler object, stepped like in a training loop (last_epoch starts at 0 after
    construction; get_lr walks the phase table)."""

    def __init__(self, max_lr, total_steps, pct_start=0.3, div_factor=25.0, final_div_factor=1e4):
        self.total_steps = total_steps
        initial = max_lr / div_factor
        self.groups = {"initial_lr": initial, "max_lr": max_lr, "min_lr": initial / final_div_factor}
        self.phases = [
            {"end_step": float(pct_start * total_steps) - 1, "start_lr": "initial_lr", "end_lr": "max_lr"},
            {"end_step": total_steps - 1, "start_lr": "max_lr", "end_lr": "min_lr"},
        ]
        self.last_epoch = 0

    @staticmethod
    def _annealing_cos(start, end, pct):
        cos_out = math.cos(math.pi * pct) + 1
        return end + (start - end) / 2.0 * cos_out

    def get_lr(self):
        step_num = self.last_epoch
        if step_num > self.total_steps:
            raise ValueError("stepped too far")
        start_step = 0.0
        for i, phase in enumerate(self.phases):
            end_step = phase["end_step"]
            if step_num <= end_step or i == len(self.phases) - 1:
                pct = (step_num - start_step) / (end_step - start_step)
                return self._annealing_cos(self.groups[phase["start_lr"]], self.groups[phase["end_lr"]], pct)
            start_step = phase["end_step"]

    def step(self):
        self.last_epoch += 1


@pytest.mark.parametrize(("lr0", "step_size", "gamma"), [(0.1, 30, 0.1), (1.0, 7, 0.5), (0.3, 1, 0.9), (0.05, 12, 0.2)])
def test_step_decay_matches_torch_step_lr(lr0, step_size, gamma):
    epochs = 100
    want = torch_step_lr(lr0, step_size, gamma, epochs)
    got = train.step_decay(np.arange(epochs), lr0, drop=gamma, every=step_size)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert [train.step_decay(e, lr0, gamma, step_size) for e in (step_size - 1, step_size)] == pytest.approx(
        [lr0, lr0 * gamma], rel=1e-12)


@pytest.mark.parametrize(("lr0", "T", "eta_min"), [(0.1, 10, 0.0), (1.0, 37, 0.01), (0.5, 2, 0.1), (0.2, 100, 0.002)])
def test_cosine_decay_matches_torch_cosine_annealing(lr0, T, eta_min):
    got = train.cosine_decay(np.arange(T + 1), T, lr0, lr_final=eta_min)
    np.testing.assert_allclose(got, torch_cosine_annealing(lr0, T, eta_min), rtol=1e-9, atol=1e-15)
    assert train.cosine_decay(0, T, lr0, eta_min) == pytest.approx(lr0, rel=1e-15)
    assert train.cosine_decay(T, T, lr0, eta_min) == pytest.approx(eta_min, abs=1e-15)
    if T % 2 == 0:
        assert train.cosine_decay(T // 2, T, lr0, eta_min) == pytest.approx((lr0 + eta_min) / 2, rel=1e-12)


@pytest.mark.parametrize(("lr", "start_factor", "W"), [(0.1, 0.01, 5), (1.0, 0.25, 20), (0.4, 0.5, 1)])
def test_warmup_matches_torch_linear_lr(lr, start_factor, W):
    steps = 3 * W + 4
    got = train.warmup(np.arange(steps), W, lr, lr_start=lr * start_factor)
    np.testing.assert_allclose(got, torch_linear_lr(lr, start_factor, W, steps), rtol=1e-9)
    assert train.warmup(W, W, lr, lr * start_factor) == lr          # reaches the target exactly at W
    assert train.warmup(W - 1, W, lr, 0.0) == pytest.approx(lr * (W - 1) / W)
    assert train.warmup(0, 0, lr) == lr


@pytest.mark.parametrize(("T", "pct", "div", "final_div"), [
    (10, 0.3, 25.0, 1e4), (100, 0.25, 25.0, 1e4), (7, 0.3, 10.0, 100.0), (1000, 0.3, 25.0, 1e4),
    (33, 0.5, 5.0, 1e3), (8, 0.1, 25.0, 1e4), (1, 0.3, 25.0, 1e4), (50, 0.0, 25.0, 1e4), (97, 0.45, 25.0, 1e4),
])
def test_one_cycle_matches_torch_one_cycle_lr_at_every_step(T, pct, div, final_div):
    sched = TorchOneCycle(2.0, T, pct, div, final_div)
    want = []
    for _ in range(T + 1):  # step 0 … T (PyTorch raises only beyond T)
        want.append(sched.get_lr())
        sched.step()
    got = train.one_cycle(np.arange(T + 1), T, 2.0, pct_start=pct, div=div, final_div=final_div)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    scalar = [train.one_cycle(t, T, 2.0, pct, div, final_div) for t in range(T + 1)]
    np.testing.assert_allclose(scalar, want, rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError):
        sched.get_lr()
    with pytest.raises(ValueError, match="step"):
        train.one_cycle(T + 1, T, 2.0, pct, div, final_div)


def test_one_cycle_boundaries():
    """Step 0 gives lr_max/div, the peak lr_max is at step pct_start·T − 1, step T − 1 gives
    lr_max/(div·final_div) — and the neighbours of the peak are below it."""
    for T, pct in [(10, 0.3), (100, 0.25), (40, 0.5), (1000, 0.3)]:
        peak = int(round(pct * T)) - 1
        assert train.one_cycle(0, T, 1.0, pct) == pytest.approx(1.0 / 25.0, rel=1e-15)
        assert train.one_cycle(peak, T, 1.0, pct) == pytest.approx(1.0, rel=1e-15)
        assert train.one_cycle(peak - 1, T, 1.0, pct) < 1.0 > train.one_cycle(peak + 1, T, 1.0, pct)
        assert train.one_cycle(T - 1, T, 1.0, pct) == pytest.approx(1.0 / (25.0 * 1e4), rel=1e-12)
        lrs = train.one_cycle(np.arange(T), T, 1.0, pct)
        assert np.all(np.diff(lrs[: peak + 1]) > 0) and np.all(np.diff(lrs[peak:]) < 0)
    # torch divides by zero where a phase has no length; we return that phase's end value
    assert train.one_cycle(0, 10, 1.0, pct_start=0.1) == 1.0
    assert train.one_cycle(10, 10, 1.0, pct_start=1.0) == pytest.approx(1.0 / 25e4)


def test_schedules_take_scalars_and_arrays():
    assert isinstance(train.step_decay(3, 0.1), float)
    assert isinstance(train.cosine_decay(np.int64(3), 10, 0.1), float)
    out = train.warmup(np.arange(6).reshape(2, 3), 4, 1.0)
    assert out.shape == (2, 3) and out.dtype == np.float64
    with pytest.raises(ValueError, match="epoch"):
        train.cosine_decay(11, 10, 0.1)


# --------------------------------------------------------------------------------------------
# regularisation
# --------------------------------------------------------------------------------------------
def test_sgd_weight_decay_step_is_gradient_descent_on_the_penalised_loss():
    """θ − lr·∇(L + λ/2·‖θ‖²), the penalty's gradient by central finite differences."""
    rng = np.random.default_rng(0)
    theta, g = rng.normal(size=(3, 4)), rng.normal(size=(3, 4))
    lr, lam = 0.3, 0.07

    def penalty(t):
        return lam / 2 * np.sum(t ** 2)

    h = 1e-6
    grad_penalty = np.zeros_like(theta)
    for idx in np.ndindex(theta.shape):
        e = np.zeros_like(theta)
        e[idx] = h
        grad_penalty[idx] = (penalty(theta + e) - penalty(theta - e)) / (2 * h)
    want = theta - lr * (g + grad_penalty)
    np.testing.assert_allclose(train.sgd_weight_decay_step(theta, g, lr, lam), want, rtol=1e-8, atol=1e-10)


def test_sgd_weight_decay_step_keeps_the_structure_and_the_inputs():
    params = [np.ones((2, 2)), np.arange(3.0)]
    grads = (np.ones((2, 2)), np.ones(3))
    before = [p.copy() for p in params]
    out = train.sgd_weight_decay_step(params, list(grads), 0.1, 0.5)
    assert isinstance(out, list) and len(out) == 2
    np.testing.assert_allclose(out[1], (1 - 0.05) * np.arange(3.0) - 0.1)
    assert all(np.array_equal(a, b) for a, b in zip(params, before))
    out = train.sgd_weight_decay_step(tuple(params), grads, 0.1, 0.5)
    assert isinstance(out, tuple)


def brute_force_early_stopping(losses, patience):
    for i in range(len(losses)):
        if i - int(np.argmin(losses[: i + 1])) >= patience:
            return i
    return None


@FAST
@given(losses=st.lists(st.integers(0, 6), min_size=1, max_size=40), patience=st.integers(1, 6))
def test_early_stopping_matches_the_definition(losses, patience):
    """Small integer losses: plenty of ties (argmin takes the first minimum)."""
    values = np.array(losses, dtype=float)
    assert train.early_stopping(values, patience) == brute_force_early_stopping(values, patience)


def test_early_stopping_examples():
    assert train.early_stopping([1.0, 0.8, 0.8, 0.8], 2) == 3        # a tie is no improvement
    assert train.early_stopping([1.0, np.inf, np.inf, 0.5], 2) == 2
    assert train.early_stopping([0.3], 1) is None
    assert isinstance(train.early_stopping([1, 2, 3], 1), int)


@pytest.mark.parametrize("classes", [2, 3, 10])
@pytest.mark.parametrize("eps", [0.0, 0.1, 0.5, 1.0])
def test_smooth_labels(classes, eps):
    y = np.random.default_rng(classes).integers(0, classes, 25)
    t = train.smooth_labels(y, classes, eps)
    assert t.shape == (25, classes) and t.dtype == np.float64
    np.testing.assert_allclose(t.sum(axis=1), 1.0)
    np.testing.assert_allclose(t[np.arange(25), y], 1 - eps)
    off = np.ones_like(t, dtype=bool)
    off[np.arange(25), y] = False
    np.testing.assert_allclose(t[off], eps / (classes - 1))


def test_smooth_labels_relation_to_pytorchs_convention():
    """PyTorch's label_smoothing=ε (true 1 − ε + ε/C, others ε/C) is ours with ε·(C − 1)/C."""
    y, C, eps = np.array([0, 2, 1, 2]), 3, 0.3
    torch_targets = np.eye(C)[y] * (1 - eps) + eps / C
    np.testing.assert_allclose(train.smooth_labels(y, C, eps * (C - 1) / C), torch_targets, rtol=1e-14)


def test_stochastic_depth_per_sample_and_in_expectation():
    rng = np.random.default_rng(1)
    x, r = rng.normal(size=(400, 3, 2)), rng.normal(size=(400, 3, 2))
    out = train.stochastic_depth(x, r, 0.7, True, rng=5)
    kept = np.all(out == x + r, axis=(1, 2))
    dropped = np.all(out == x, axis=(1, 2))
    assert np.all(kept ^ dropped)
    # the coins are Bernoulli(p), one per sample: a binomial test
    assert stats.binomtest(int(kept.sum()), kept.size, 0.7).pvalue > 1e-4
    # the evaluation output is the expectation of the training output
    mean = np.mean([train.stochastic_depth(x[:5], r[:5], 0.7, True, rng=s) for s in range(4000)], axis=0)
    np.testing.assert_allclose(mean, train.stochastic_depth(x[:5], r[:5], 0.7, False), atol=0.07)
    np.testing.assert_array_equal(train.stochastic_depth(x, r, 1.0, True, rng=0), x + r)
    np.testing.assert_array_equal(train.stochastic_depth(x, r, 0.0, True, rng=0), x)
    np.testing.assert_array_equal(train.stochastic_depth(x, r, 0.3, True, rng=9), train.stochastic_depth(x, r, 0.3, True, rng=9))


# --------------------------------------------------------------------------------------------
# augmentation
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("box", "out"), [((3, 5, 20, 30), (8, 11)), ((0, 0, 40, 50), (40, 50)), ((10, 7, 9, 6), (20, 13)),
                                          ((2, 2, 15, 15), (15, 4)), ((0, 1, 1, 7), (3, 3))])
@pytest.mark.parametrize("channels", [None, 3])
def test_resize_matches_opencv_and_skimage(box, out, channels):
    """The resize of the crop is OpenCV's INTER_LINEAR (half-pixel centres), which is
    skimage.transform.resize(order=1, mode='edge', anti_aliasing=False)."""
    from skimage.transform import resize

    rng = np.random.default_rng(4)
    image = rng.random((40, 50) if channels is None else (40, 50, channels))
    top, left, h, w = box
    got = _augment._resample_boxes(image[None], np.array([top]), np.array([left]), np.array([h]), np.array([w]), *out)[0]
    crop = image[top: top + h, left: left + w]
    want_cv = cv2.resize(crop, (out[1], out[0]), interpolation=cv2.INTER_LINEAR).reshape(got.shape)
    np.testing.assert_allclose(got, want_cv, atol=2e-6)  # OpenCV keeps its weights in float32
    want_sk = resize(crop, out + crop.shape[2:], order=1, mode="edge", anti_aliasing=False)
    np.testing.assert_allclose(got, want_sk, atol=1e-12)


def torchvision_box(gen, H, W, scale, ratio):
    """torchvision.transforms.RandomResizedCrop.get_params, transcribed (10 attempts, then the
    central fallback)."""
    area = H * W
    for _ in range(10):
        target = area * gen.uniform(*scale)
        aspect = math.exp(gen.uniform(math.log(ratio[0]), math.log(ratio[1])))
        w, h = int(round(math.sqrt(target * aspect))), int(round(math.sqrt(target / aspect)))
        if 0 < w <= W and 0 < h <= H:
            return int(gen.integers(0, H - h + 1)), int(gen.integers(0, W - w + 1)), h, w
    return 0, 0, H, W


def test_random_resized_crop_box_distribution():
    """Area fractions uniform in `scale`, log aspect ratios uniform in log `ratio` (KS tests,
    a large image so that rounding to whole pixels does not matter), positions uniform."""
    gen = np.random.default_rng(0)
    H, W = 400, 500
    top, left, h, w = _augment._crop_boxes(4000, H, W, (0.2, 0.6), (0.8, 1.25), gen)  # every candidate fits
    assert stats.kstest(h * w / (H * W), stats.uniform(0.2, 0.4).cdf).pvalue > 1e-3
    assert stats.kstest(np.log(w / h), stats.uniform(np.log(0.8), np.log(1.25 / 0.8)).cdf).pvalue > 1e-3
    assert np.all((top >= 0) & (left >= 0) & (top + h <= H) & (left + w <= W))
    assert stats.kstest(top / (H - h), "uniform").pvalue > 1e-3


def test_random_resized_crop_boxes_match_torchvision_when_candidates_are_rejected():
    """With ratios the image cannot always hold, candidates are rejected; the boxes are then
    distributed like torchvision's (two-sample KS tests against its sampler)."""
    H, W, scale, ratio = 40, 50, (0.3, 0.9), (0.4, 2.5)
    top, left, h, w = _augment._crop_boxes(3000, H, W, scale, ratio, np.random.default_rng(1))
    gen = np.random.default_rng(2)
    ref = np.array([torchvision_box(gen, H, W, scale, ratio) for _ in range(3000)])
    for ours, theirs in ((h * w, ref[:, 2] * ref[:, 3]), (w / h, ref[:, 3] / ref[:, 2]), (top, ref[:, 0])):
        assert stats.ks_2samp(ours, theirs).pvalue > 1e-3


def test_random_resized_crop_of_a_plane_is_a_plane():
    rows, cols = np.mgrid[0:60, 0:80].astype(float)
    image = 2.0 * rows - 0.5 * cols + 3.0
    for seed in range(20):
        out = train.random_resized_crop(image, (12, 9), scale=(0.3, 0.6), rng=seed)
        assert out.shape == (12, 9)
        du, dv = np.diff(out, axis=0), np.diff(out, axis=1)
        np.testing.assert_allclose(du, du[0, 0], atol=1e-9)
        np.testing.assert_allclose(dv, dv[0, 0], atol=1e-9)
        h, w = du[0, 0] / 2.0 * 12, dv[0, 0] / -0.5 * 9   # crop size from the slopes
        assert 0.3 * 4800 - 60 <= h * w <= 0.6 * 4800 + 60
        assert 3 / 4 - 0.1 <= w / h <= 4 / 3 + 0.1
    colour = np.random.default_rng(2).random((30, 30, 3))
    assert train.random_resized_crop(colour, 7, rng=0).shape == (7, 7, 3)
    assert np.array_equal(train.random_resized_crop(colour, 7, rng=3), train.random_resized_crop(colour, 7, rng=3))


def test_random_resized_crop_fallback_is_the_central_crop():
    """When no candidate fits (scale 1 with a ratio the image does not have) torchvision's
    fallback: the whole height (or width), clamped to the ratio range, centred."""
    image = np.arange(20 * 40, dtype=float).reshape(20, 40)   # ratio 2
    top, left, h, w = _augment._crop_boxes(1, 20, 40, (1.0, 1.0), (0.5, 1.0), np.random.default_rng(0))
    assert (h[0], w[0]) == (20, 20) and (top[0], left[0]) == (0, 10)
    out = train.random_resized_crop(image, (20, 20), scale=(1.0, 1.0), ratio=(0.5, 1.0), rng=0)
    np.testing.assert_array_equal(out, image[:, 10:30])


def test_cutout_coverage_matches_the_uniform_centre():
    """P(pixel erased) = (number of centres whose square covers it) / (H·W)."""
    H, W, size = 7, 9, 3
    image = np.ones((H, W))
    counts = np.zeros((H, W))
    draws = 6000
    gen = np.random.default_rng(0)
    for _ in range(draws):
        counts += train.cutout(image, size, rng=gen) == 0
    expected = np.zeros((H, W))
    for cy in range(H):
        for cx in range(W):
            r0, c0 = cy - size // 2, cx - size // 2
            expected[max(r0, 0): r0 + size, max(c0, 0): c0 + size] += 1
    expected /= H * W
    se = np.sqrt(expected * (1 - expected) / draws)
    assert np.all(np.abs(counts / draws - expected) <= 5 * se + 1e-12)


def test_cutout_square():
    image = np.random.default_rng(1).uniform(0.1, 1, (30, 40, 3))
    for seed in range(30):
        out = train.cutout(image, 6, rng=seed)
        erased = np.all(out == 0, axis=2)
        assert np.array_equal(erased, np.any(out != image, axis=2))
        rows, cols = np.flatnonzero(erased.any(1)), np.flatnonzero(erased.any(0))
        assert erased[rows[0]: rows[-1] + 1, cols[0]: cols[-1] + 1].all()
        assert len(rows) == 6 or rows[0] == 0 or rows[-1] == 29
        assert len(cols) == 6 or cols[0] == 0 or cols[-1] == 39
    assert train.cutout(np.ones((4, 5)), 20, rng=0).sum() == 0.0


def test_mixup_lambda_is_beta_and_partners_a_permutation():
    x = np.random.default_rng(0).random((12, 5))
    y = np.eye(4)[np.arange(12) % 4]
    lams = []
    for seed in range(1500):
        xm, ym, lam = train.mixup(x, y, alpha=0.4, rng=seed)
        lams.append(lam)
        if seed < 20:
            # recover the partners: x_mixed − λx = (1 − λ) x[π]
            rest = (xm - lam * x) / (1 - lam)
            partners = np.argmin(((rest[:, None] - x[None]) ** 2).sum(-1), axis=1)
            assert sorted(partners) == list(range(12))
            np.testing.assert_allclose(ym, lam * y + (1 - lam) * y[partners], atol=1e-12)
    assert stats.kstest(lams, stats.beta(0.4, 0.4).cdf).pvalue > 1e-3


def original_cutmix_box(H, W, lam, cx, cy):
    """The box of the CutMix authors' rand_bbox (clovaai/CutMix-PyTorch), given the draws."""
    cut_rat = np.sqrt(1.0 - lam)
    cut_w, cut_h = int(W * cut_rat), int(H * cut_rat)
    bbx1, bby1 = np.clip(cx - cut_w // 2, 0, W), np.clip(cy - cut_h // 2, 0, H)
    bbx2, bby2 = np.clip(cx + cut_w // 2, 0, W), np.clip(cy + cut_h // 2, 0, H)
    return bby1, bby2, bbx1, bbx2


def test_cutmix_box_label_weights_and_draws():
    x = np.random.default_rng(3).random((10, 2, 13, 17))
    y = np.eye(5)[np.arange(10) % 5]
    lams = []
    for seed in range(300):
        xm, ym, lam = train.cutmix(x, y, alpha=1.0, rng=seed)
        gen = np.random.default_rng(seed)               # the documented draw order
        lam0, perm = gen.beta(1.0, 1.0), gen.permutation(10)
        cy, cx = gen.integers(0, 13), gen.integers(0, 17)
        y1, y2, x1, x2 = original_cutmix_box(13, 17, lam0, cx, cy)
        want = x.copy()
        want[..., y1:y2, x1:x2] = x[perm][..., y1:y2, x1:x2]
        np.testing.assert_array_equal(xm, want)
        assert lam == pytest.approx(1 - (y2 - y1) * (x2 - x1) / (13 * 17), abs=1e-15)
        np.testing.assert_allclose(ym, lam * y + (1 - lam) * y[perm], atol=1e-15)
        lams.append(lam0)
    assert stats.kstest(lams, "uniform").pvalue > 1e-3


def test_random_search_distributions():
    space = {"lr": {"low": 1e-5, "high": 1e-1, "log": True}, "p": {"low": 0.1, "high": 0.6},
             "bs": [16, 32, 64, 128], "opt": ("sgd", "adam")}
    trials = train.random_search(space, 4000, rng=0)
    assert len(trials) == 4000 and all(list(t) == list(space) for t in trials)
    lr = np.array([t["lr"] for t in trials])
    assert lr.min() >= 1e-5 and lr.max() <= 1e-1
    assert stats.kstest(lr, stats.loguniform(1e-5, 1e-1).cdf).pvalue > 1e-3
    assert stats.kstest([t["p"] for t in trials], stats.uniform(0.1, 0.5).cdf).pvalue > 1e-3
    counts = [sum(t["bs"] == v for t in trials) for v in (16, 32, 64, 128)]
    assert stats.chisquare(counts).pvalue > 1e-3
    assert {t["opt"] for t in trials} == {"sgd", "adam"}
    assert all(type(t["bs"]) is int for t in trials[:10])
    assert train.random_search(space, 0, rng=0) == []
    assert train.random_search(space, 5, rng=7) == train.random_search(space, 5, rng=7)


def test_random_search_covers_an_important_axis_better_than_a_grid():
    """Bergstra & Bengio's point: 9 random trials give 9 distinct values of each parameter,
    a 3×3 grid only 3."""
    found = train.random_search({"a": {"low": 0.0, "high": 1.0}, "b": {"low": 0.0, "high": 1.0}}, 9, rng=1)
    assert len({round(t["a"], 12) for t in found}) == 9


def test_ensemble_and_ema():
    rng = np.random.default_rng(5)
    members = [rng.normal(size=(4, 3)) for _ in range(5)]
    np.testing.assert_allclose(train.ensemble_predict(members), sum(members) / 5, rtol=1e-14)
    np.testing.assert_allclose(train.ensemble_predict(np.stack(members)), sum(members) / 5, rtol=1e-14)
    # EMA over a sequence = the closed form β^T·ema0 + (1 − β)·Σ β^(T−1−t)·θ_t
    beta, thetas = 0.9, [rng.normal(size=3) for _ in range(30)]
    ema = np.zeros(3)
    for theta in thetas:
        ema = train.ema_update(ema, theta, beta)
    closed = sum((1 - beta) * beta ** (len(thetas) - 1 - t) * th for t, th in enumerate(thetas))
    np.testing.assert_allclose(ema, closed, rtol=1e-12)
    out = train.ema_update((np.ones(2), np.zeros(1)), (np.zeros(2), np.ones(1)), 0.75)
    assert isinstance(out, tuple)
    np.testing.assert_allclose(out[0], 0.75)
    np.testing.assert_allclose(out[1], 0.25)


# --------------------------------------------------------------------------------------------
# bad input: clear errors naming the argument
# --------------------------------------------------------------------------------------------
BAD_NUMBERS = st.sampled_from([np.nan, np.inf, -1.0, "a", None, True, 1j])


@FAST
@given(value=BAD_NUMBERS, which=st.sampled_from(["epoch", "lr0", "drop", "every"]))
def test_step_decay_bad_input(value, which):
    args = {"epoch": 3, "lr0": 0.1, "drop": 0.1, "every": 30}
    args[which] = value
    with pytest.raises((ValueError, TypeError), match=which):
        train.step_decay(**args)


@FAST
@given(value=BAD_NUMBERS, which=st.sampled_from(["step", "total_steps", "lr_max", "pct_start", "div", "final_div"]))
def test_one_cycle_bad_input(value, which):
    args = {"step": 3, "total_steps": 10, "lr_max": 1.0, "pct_start": 0.3, "div": 25.0, "final_div": 1e4}
    args[which] = value
    with pytest.raises((ValueError, TypeError), match=which):
        train.one_cycle(**args)


@pytest.mark.parametrize(("call", "name"), [
    (lambda: train.cosine_decay(3, 0, 0.1), "epochs"),
    (lambda: train.cosine_decay(-1, 10, 0.1), "epoch"),
    (lambda: train.warmup(3, -2, 0.1), "warmup_steps"),
    (lambda: train.warmup(3, 2.5, 0.1), "warmup_steps"),
    (lambda: train.one_cycle(3, 10, 1.0, pct_start=1.5), "pct_start"),
    (lambda: train.sgd_weight_decay_step(np.ones(3), np.ones(2), 0.1, 0.1), "grads"),
    (lambda: train.sgd_weight_decay_step([np.ones(3)], np.ones(3), 0.1, 0.1), "grads"),
    (lambda: train.sgd_weight_decay_step(np.ones(3), np.ones(3), -0.1, 0.1), "lr"),
    (lambda: train.sgd_weight_decay_step(np.ones(3), np.ones(3), 0.1, np.nan), "weight_decay"),
    (lambda: train.sgd_weight_decay_step([], [], 0.1, 0.1), "params"),
    (lambda: train.early_stopping([1.0, np.nan], 2), "val_losses"),
    (lambda: train.early_stopping([[1.0]], 2), "val_losses"),
    (lambda: train.early_stopping([1.0, 2.0], 0), "patience"),
    (lambda: train.smooth_labels([0, 3], 3, 0.1), "y"),
    (lambda: train.smooth_labels([0, 1.5], 3, 0.1), "y"),
    (lambda: train.smooth_labels([0, 1], 1, 0.1), "classes"),
    (lambda: train.smooth_labels([0, 1], 3, 1.1), "eps"),
    (lambda: train.smooth_labels("01", 3, 0.1), "y"),
    (lambda: train.stochastic_depth(np.ones((3, 2)), np.ones((3, 3)), 0.5, True), "residual"),
    (lambda: train.stochastic_depth(np.ones((3, 2)), np.ones((3, 2)), 1.5, True), "survival_prob"),
    (lambda: train.stochastic_depth(np.ones((3, 2)), np.ones((3, 2)), 0.5, "yes"), "training"),
    (lambda: train.stochastic_depth(np.ones((3, 2)), np.ones((3, 2)), 0.5, True, rng="x"), "rng"),
    (lambda: train.random_resized_crop(np.ones((5, 5)), 0), "output_size"),
    (lambda: train.random_resized_crop(np.ones((5, 5)), (3, 3), scale=(0.5, 0.2)), "scale"),
    (lambda: train.random_resized_crop(np.ones((5, 5)), (3, 3), scale=(0.5, 1.5)), "scale"),
    (lambda: train.random_resized_crop(np.ones((5, 5)), (3, 3), ratio=(-1, 2)), "ratio"),
    (lambda: train.random_resized_crop(np.ones((5, 5, 2)), 3), "image"),
    (lambda: train.random_resized_crop(np.full((5, 5), np.nan), 3), "image"),
    (lambda: train.cutout(np.ones((5, 5)), 0), "size"),
    (lambda: train.cutout(np.ones(5), 2), "image"),
    (lambda: train.mixup(np.ones((4, 2)), np.ones((3, 2))), "y_onehot"),
    (lambda: train.mixup(np.ones((4, 2)), np.eye(4), alpha=0.0), "alpha"),
    (lambda: train.cutmix(np.ones((4, 5)), np.eye(4)), "x"),
    (lambda: train.cutmix(np.ones((4, 5, 5)), np.eye(4), alpha=-1.0), "alpha"),
    (lambda: train.random_search({}, 3), "space"),
    (lambda: train.random_search({"a": []}, 3), "space"),
    (lambda: train.random_search({"a": {"low": 1.0}}, 3), "space"),
    (lambda: train.random_search({"a": {"low": 0.0, "high": 1.0, "log": True}}, 3), "low"),
    (lambda: train.random_search({"a": {"low": 2.0, "high": 1.0}}, 3), "low"),
    (lambda: train.random_search({"a": 3}, 3), "space"),
    (lambda: train.random_search({"a": [1]}, -1), "trials"),
    (lambda: train.ensemble_predict([]), "logits_list"),
    (lambda: train.ensemble_predict([np.ones((2, 3)), np.ones((3, 2))]), "logits_list"),
    (lambda: train.ema_update(np.ones(3), np.ones(3), decay=1.5), "decay"),
    (lambda: train.ema_update([np.ones(3), np.ones(2)], [np.ones(3)]), "params"),
])
def test_bad_input_raises_naming_the_argument(call, name):
    with pytest.raises((ValueError, TypeError), match=name):
        call()


@FAST
@given(shape=st.sampled_from([(3,), (2, 2), (4, 1)]), bad=st.sampled_from([np.nan, np.inf]))
def test_non_finite_parameters_are_refused(shape, bad):
    params = np.ones(shape)
    params.flat[0] = bad
    with pytest.raises(ValueError, match="params"):
        train.sgd_weight_decay_step(params, np.ones(shape), 0.1, 0.1)
    with pytest.raises(ValueError, match="ema_params"):
        train.ema_update(params, np.ones(shape))


def test_inputs_are_not_modified():
    rng = np.random.default_rng(0)
    x = rng.random((6, 8, 8))
    y = np.eye(6)
    image = rng.random((10, 12, 3))
    copies = [a.copy() for a in (x, y, image)]
    train.mixup(x, y, rng=0)
    train.cutmix(x, y, rng=0)
    train.cutout(image, 4, rng=0)
    train.random_resized_crop(image, 5, rng=0)
    train.stochastic_depth(x, x, 0.5, True, rng=0)
    for a, b in zip((x, y, image), copies):
        assert np.array_equal(a, b)


# --------------------------------------------------------------------------------------------
# the teaching model
# --------------------------------------------------------------------------------------------
def test_backward_matches_finite_differences():
    rng = np.random.default_rng(0)
    params = _models.init_params((5, 7, 4), rng)
    X = rng.normal(size=(6, 5))
    targets = train.smooth_labels(rng.integers(0, 4, 6), 4, 0.1)
    logits, activations, masks = _models.forward(params, X, cache=True)
    grads = _models._backward(params, activations, masks, logits, targets)
    h = 1e-6
    for k, p in enumerate(params):
        for idx in list(np.ndindex(p.shape))[:6]:
            plus = [q.copy() for q in params]
            minus = [q.copy() for q in params]
            plus[k][idx] += h
            minus[k][idx] -= h
            numeric = (_models.cross_entropy(_models.forward(plus, X), targets)
                       - _models.cross_entropy(_models.forward(minus, X), targets)) / (2 * h)
            assert grads[k][idx] == pytest.approx(numeric, rel=1e-5, abs=1e-8)


def test_dropout_masks_and_their_gradient():
    rng = np.random.default_rng(1)
    params = _models.init_params((4, 50, 3), rng)
    X = rng.normal(size=(3, 4))
    logits, activations, masks = _models.forward(params, X, dropout=0.5, rng=2, cache=True)
    assert set(np.unique(masks[0])) <= {0.0, 2.0}
    # a unit dropped for every sample of the batch gets no gradient
    targets = np.eye(3)[[0, 1, 2]]
    grads = _models._backward(params, activations, masks, logits, targets)
    dropped_everywhere = np.all(masks[0] == 0, axis=0)
    assert dropped_everywhere.any()
    assert np.all(grads[0][:, dropped_everywhere] == 0) and np.all(grads[1][dropped_everywhere] == 0)


def test_training_learns_the_digits_quickly():
    (X, y), (Xt, yt) = cvkit.data.digits()
    recipe = _models.Recipe(epochs=5, schedule="cosine", warmup_epochs=1, lr=0.2)
    result = _models.train(X, y, recipe, rng=0, X_val=Xt, y_val=yt)
    assert result.epoch_loss[-1] < result.epoch_loss[0]
    assert _models.accuracy(result.params, Xt, yt) > 0.9
    assert result.val_accuracy.shape == (5,) and not result.diverged
    assert result.lrs[0] == 0.0 and result.lrs.max() == pytest.approx(0.2)


def test_divergence_is_detected_without_warnings(recwarn):
    (X, y), _ = cvkit.data.digits()
    result = _models.train(X[:200], y[:200], _models.Recipe(epochs=3, lr=1e200), rng=0)  # overflows
    assert result.diverged and np.isnan(result.epoch_loss[-1])
    assert len(recwarn) == 0
    # a rate far too high but finite only makes the loss explode (and the ReLUs die)
    result = _models.train(X[:200], y[:200], _models.Recipe(epochs=3, lr=1e3), rng=0)
    assert not result.diverged and result.epoch_loss[0] > 1e3


def test_every_recipe_option_runs_and_uses_the_registry():
    (X, y), _ = cvkit.data.digits()
    X, y = X[:128], y[:128]
    recipe = _models.Recipe(epochs=2, batch_size=32, schedule="one_cycle", dropout=0.2, weight_decay=1e-3,
                            label_smoothing=0.1, augment=("crop", "cutout", "mixup", "cutmix"), ema_decay=0.9)
    result = _models.train(X, y, recipe, rng=0)
    assert result.ema_params is not None and np.all(np.isfinite(result.step_loss))
    for schedule in ("constant", "step", "cosine"):
        lrs = _models.learning_rates(_models.Recipe(epochs=6, schedule=schedule, warmup_epochs=1, lr=0.1), 4)
        assert lrs.shape == (24,) and lrs[0] == 0.0 and lrs[4] == pytest.approx(0.1)

    @cvkit.student("train.warmup")
    def warmup(step, warmup_steps, lr_target, lr_start=0.0):  # a student's (scalar-only) version
        return 0.123

    try:
        with cvkit.use("student"):
            lrs = _models.learning_rates(_models.Recipe(epochs=2, schedule="cosine", warmup_epochs=1, lr=0.1), 4)
        assert np.all(lrs[:4] == 0.123) and lrs[4] == pytest.approx(0.1)
    finally:
        registry.provider("student").remove("train.warmup")


def test_recipe_table_small():
    (X, y), (Xt, yt) = cvkit.data.digits()
    steps = _models.RECIPE_STEPS[:2] + (("   (alone) + mixup", {"augment": ("mixup",)}, 1, False),
                                        ("+ ensemble of 2", {}, 2, True))
    rows = _models.recipe_table((X[:300], y[:300]), (Xt, yt), seeds=(0, 1), steps=steps, epochs=2)
    assert [r.members for r in rows] == [1, 1, 1, 2]
    assert rows[2].recipe.augment == ("mixup",) and rows[3].recipe.augment == ()
    assert all(r.test.shape == (2,) and np.all((r.test > 0.3) & (r.test <= 1)) for r in rows)
    table = _models.format_recipe_table(rows)
    assert table.count("\n") == 5 and "± " in table


def test_the_notebook_ships_the_recipe_table_of_these_steps():
    """The full table (``benchmarks/recipe_table.py --check`` reproduces its numbers) ships with
    the chapter as per-seed data, ``recipe_table.csv``: one block of 5 seeds per step of
    ``net.RECIPE_STEPS``, in order, and the notebook shows it from that file."""
    import csv
    import json
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "lectures" / "ch12_training"
    rows = list(csv.DictReader((folder / "recipe_table.csv").open()))
    steps = list(dict.fromkeys(row["step"] for row in rows))
    assert steps == [label for label, *_ in _models.RECIPE_STEPS]
    for step in steps:
        assert sorted(int(r["seed"]) for r in rows if r["step"] == step) == [0, 1, 2, 3, 4], step
    assert all(0.0 < float(r["test_accuracy"]) <= 1.0 for r in rows)
    cells = json.loads((folder / "ch12_training.ipynb").read_text())["cells"]
    assert any("recipe_table.csv" in "".join(c["source"]) for c in cells if c["cell_type"] == "code")
    prose = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")
    assert "5 seeds" in prose
