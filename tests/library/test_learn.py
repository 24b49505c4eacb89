"""cvkit.learn against oracles (scikit-learn, SciPy, brute-force definitions), its documented
properties, the issue's targets, and clear errors on bad input.

Targets checked here: digits test accuracy ≥ 0.95 for the linear classifier trained by
``sgd_train`` and ≥ 0.97 for 1-NN; analytic gradients equal ``numerical_gradient`` to 1e-6
relative; softmax finite for scores ±1e4; k-means inertia within 1 % of scikit-learn's
``KMeans``; bag-of-visual-words texture classification ≥ 0.9 test accuracy.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.special
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cvkit import data, learn

RNG = np.random.default_rng(20260409)


def _rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.fixture(scope="module")
def digits():
    return data.digits()


# --------------------------------------------------------------------------------------------
# linear classifier pieces
# --------------------------------------------------------------------------------------------
def test_linear_scores_is_the_affine_map():
    X, W, b = RNG.normal(size=(7, 5)), RNG.normal(size=(3, 5)), RNG.normal(size=3)
    brute = np.array([[W[j] @ X[i] + b[j] for j in range(3)] for i in range(7)])
    assert np.allclose(learn.linear_scores(X, W, b), brute, rtol=1e-12, atol=1e-12)
    u8 = RNG.integers(0, 256, (4, 5), dtype=np.uint8)  # not rescaled
    assert np.allclose(learn.linear_scores(u8, W, b), u8.astype(float) @ W.T + b)


def test_softmax_matches_scipy_and_stays_finite():
    s = RNG.normal(0, 3, (6, 5))
    assert np.allclose(learn.softmax(s), scipy.special.softmax(s, axis=1), rtol=1e-12, atol=1e-15)
    assert np.allclose(learn.softmax(s[0]), scipy.special.softmax(s[0]), rtol=1e-12)
    huge = np.array([[1e4, 0.0, -1e4], [-1e4, -1e4 + 1.0, -1e4 + 2.0], [1e300, -1e300, 0.0]])
    p = learn.softmax(huge)
    assert np.all(np.isfinite(p)) and np.allclose(p.sum(axis=1), 1.0)
    assert np.allclose(p[1], scipy.special.softmax([0.0, 1.0, 2.0]))
    assert np.allclose(learn.softmax(s + 1234.5), learn.softmax(s))  # shift invariance


def test_cross_entropy_matches_sklearn_log_loss_and_its_gradient_is_exact():
    from sklearn.metrics import log_loss

    s = RNG.normal(0, 2, (9, 4))
    y = RNG.integers(0, 4, 9)
    loss, g = learn.cross_entropy(s, y)
    assert loss == pytest.approx(log_loss(y, scipy.special.softmax(s, axis=1), labels=range(4)), rel=1e-12)
    numeric = learn.numerical_gradient(lambda v: learn.cross_entropy(v, y)[0], s)
    assert _rel(g, numeric) < 1e-6
    big, y_big = np.array([[1e4, 0.0, -1e4]]), np.array([2])
    loss_big, g_big = learn.cross_entropy(big, y_big)
    assert loss_big == pytest.approx(2e4) and np.all(np.isfinite(g_big))


@pytest.mark.parametrize("reg", [0.0, 0.3])
def test_linear_gradients_equal_the_numerical_gradient(reg):
    X, y = RNG.normal(size=(12, 6)), RNG.integers(0, 4, 12)
    W, b = RNG.normal(0, 0.5, (4, 6)), RNG.normal(size=4)
    loss, dW, db = learn.linear_loss_and_grad(W, b, X, y, reg)
    nW = learn.numerical_gradient(lambda v: learn.linear_loss_and_grad(v, b, X, y, reg)[0], W)
    nb = learn.numerical_gradient(lambda v: learn.linear_loss_and_grad(W, v, X, y, reg)[0], b)
    assert _rel(dW, nW) < 1e-6 and _rel(db, nb) < 1e-6
    assert loss == pytest.approx(learn.cross_entropy(X @ W.T + b, y)[0] + reg * np.sum(W ** 2), rel=1e-12)


def test_numerical_gradient_properties():
    x = np.array([[0.5, -1.0, 2.0], [1.5, 0.0, -0.3]])
    before = x.copy()
    g = learn.numerical_gradient(lambda v: float(np.sum(np.sin(v) * v ** 2)), x)
    assert np.array_equal(x, before)
    assert g.shape == x.shape and _rel(g, np.cos(x) * x ** 2 + 2 * x * np.sin(x)) < 1e-8
    # central differences: the truncation error is h²·f'''/6 (here f = x³: exactly h²)
    assert learn.numerical_gradient(lambda v: float(np.sum(v ** 3)), np.array([1.0]), eps=0.1)[0] == pytest.approx(3.01)
    assert learn.numerical_gradient(lambda v: float(v.sum() ** 2), np.array([1, 2]))[0] == pytest.approx(6.0)  # int x
    with pytest.raises(TypeError, match="f must return a single number"):
        learn.numerical_gradient(lambda v: v, np.ones(3))


@pytest.mark.parametrize("layout", ["transposed", "fortran", "axes swapped", "strided"])
def test_numerical_gradient_of_a_non_contiguous_x(layout):
    # the coordinates must be moved in the array f sees, whatever the memory layout of x
    base = np.arange(1.0, 25.0).reshape(2, 3, 4) / 7
    x = {"transposed": base[0].T, "fortran": np.asfortranarray(base[1]),
         "axes swapped": base.transpose(1, 0, 2), "strided": base[:, ::2, ::-1]}[layout]
    before = x.copy()
    g = learn.numerical_gradient(lambda v: float(np.sum(v ** 2)), x)
    assert g.shape == x.shape and _rel(g, 2 * x) < 1e-9
    assert np.array_equal(x, before)
    with pytest.raises(TypeError, match="f must be a callable"):
        learn.numerical_gradient(np.ones(3), np.ones(3))


def test_sgd_full_batch_is_gradient_descent_from_zero():
    X, y = RNG.normal(size=(15, 3)), RNG.integers(0, 3, 15)
    W, b, losses = learn.sgd_train(X, y, 3, 0.4, 4, 15, reg=0.1, rng=5)
    Wm, bm, lm = np.zeros((3, 3)), np.zeros(3), []
    for _ in range(4):
        loss, dW, db = learn.linear_loss_and_grad(Wm, bm, X, y, 0.1)
        lm.append(loss)
        Wm, bm = Wm - 0.4 * dW, bm - 0.4 * db
    assert np.allclose(W, Wm, rtol=1e-12, atol=1e-14) and np.allclose(b, bm) and np.allclose(losses, lm)
    assert losses[0] == pytest.approx(np.log(3))


def test_sgd_reproducible_shuffled_and_counting_batches():
    X, y = RNG.normal(size=(30, 2)), RNG.integers(0, 2, 30)
    a = learn.sgd_train(X, y, 2, 0.1, 3, 7, rng=1)
    b = learn.sgd_train(X, y, 2, 0.1, 3, 7, rng=1)
    c = learn.sgd_train(X, y, 2, 0.1, 3, 7, rng=2)
    assert all(np.array_equal(u, v) for u, v in zip(a, b))
    assert not np.allclose(a[0], c[0])
    calls = []

    def counting(W, b_, Xb, yb, reg=0.0):
        calls.append(len(Xb))
        return learn.linear_loss_and_grad(W, b_, Xb, yb, reg)

    import cvkit

    with cvkit.registry.use("student"):
        prov = cvkit.registry.provider("student")
        prov.add("learn.linear_loss_and_grad", counting)
        try:
            learn.sgd_train(X, y, 2, 0.1, 2, 7, rng=0)
        finally:
            prov.remove("learn.linear_loss_and_grad")
    assert calls == [7, 7, 7, 7, 2] * 2  # ⌈30/7⌉ batches per epoch, the last one smaller


def test_sgd_reaches_the_regularised_optimum_of_sklearn():
    """min mean CE + λ‖W‖² is sklearn's multinomial LogisticRegression with C = 1/(2λN)."""
    from sklearn.linear_model import LogisticRegression

    X, y = RNG.normal(size=(60, 3)), RNG.integers(0, 3, 60)
    X[y == 1] += 1.0
    lam = 0.05
    sk = LogisticRegression(C=1 / (2 * lam * 60), tol=1e-10, max_iter=10000).fit(X, y)

    def objective(W, b):
        return learn.cross_entropy(X @ W.T + b, y)[0] + lam * np.sum(W ** 2)

    W, b, _ = learn.sgd_train(X, y, 3, 0.5, 3000, 60, reg=lam, rng=0)
    assert objective(W, b) == pytest.approx(objective(sk.coef_, sk.intercept_), abs=1e-6)
    # the optimum is unique up to a common shift of b (softmax is shift invariant)
    assert np.allclose(W, sk.coef_, atol=1e-3)
    assert np.allclose(b - b.mean(), sk.intercept_ - sk.intercept_.mean(), atol=1e-3)


def test_digits_targets(digits):
    (X_train, y_train), (X_test, y_test) = digits
    W, b, losses = learn.sgd_train(X_train, y_train, 10, 0.5, 30, 32, reg=1e-4, rng=0)
    accuracy = np.mean(learn.linear_scores(X_test, W, b).argmax(axis=1) == y_test)
    assert accuracy >= 0.95, accuracy
    assert losses[-1] < losses[0]
    assert np.mean(learn.knn_predict(X_train, y_train, X_test, k=1) == y_test) >= 0.97


def test_top_k_accuracy_matches_sklearn_without_ties_and_counts_ties_as_hits():
    from sklearn.metrics import top_k_accuracy_score

    s, y = RNG.normal(size=(40, 6)), RNG.integers(0, 6, 40)
    for k in (1, 2, 3, 5):
        assert learn.top_k_accuracy(s, y, k) == pytest.approx(top_k_accuracy_score(y, s, k=k, labels=range(6)))
    tied = np.array([[3.0, 2.0, 2.0, 1.0]])
    assert learn.top_k_accuracy(tied, np.array([2]), k=2) == 1.0  # class 2 ties with class 1 at place 2
    assert learn.top_k_accuracy(tied, np.array([1]), k=2) == 1.0
    assert learn.top_k_accuracy(tied, np.array([3]), k=3) == 0.0  # beaten by three scores
    assert learn.top_k_accuracy(tied, np.array([3]), k=4) == 1.0
    with pytest.raises(ValueError, match="k must be at most"):
        learn.top_k_accuracy(s, y, k=7)


# --------------------------------------------------------------------------------------------
# kNN
# --------------------------------------------------------------------------------------------
def _knn_brute(X_train, y_train, X_test, k, metric):
    out = []
    for q in X_test:
        d = [float(np.sum((a - q) ** 2)) if metric == "l2" else float(np.sum(np.abs(a - q))) for a in X_train]
        order = sorted(range(len(X_train)), key=lambda i: (d[i], i))[:k]
        votes = np.bincount(np.asarray(y_train)[order], minlength=int(np.max(y_train)) + 1)
        out.append(int(np.argmax(votes)))
    return np.array(out)


@pytest.mark.parametrize("metric", ["l2", "l1"])
@pytest.mark.parametrize("k", [1, 2, 3, 4, 6])
def test_knn_matches_brute_force_with_ties(metric, k):
    X = RNG.integers(0, 4, (40, 2)).astype(float)   # a small grid: many equal distances
    y = RNG.integers(0, 4, 40)
    Q = RNG.integers(0, 4, (30, 2)).astype(float)
    assert np.array_equal(learn.knn_predict(X, y, Q, k, metric), _knn_brute(X, y, Q, k, metric))


def test_knn_fast_l2_path_with_duplicates_and_large_values():
    X = np.repeat(RNG.normal(size=(30, 5)) * 1e3, 3, axis=0)  # each point three times
    y = RNG.integers(0, 3, 90)
    Q = X[::7] + RNG.normal(size=(13, 5)) * 1e-3
    for k in (1, 2, 5):
        assert np.array_equal(learn.knn_predict(X, y, Q, k), _knn_brute(X, y, Q, k, "l2"))


@pytest.mark.parametrize(("k", "metric", "p"), [(1, "l2", 2), (3, "l2", 2), (5, "l1", 1)])
def test_knn_agrees_with_sklearn_on_digits(digits, k, metric, p):
    from sklearn.neighbors import KNeighborsClassifier

    (X_train, y_train), (X_test, y_test) = digits
    ours = learn.knn_predict(X_train, y_train, X_test, k, metric)
    theirs = KNeighborsClassifier(n_neighbors=k, p=p, algorithm="brute").fit(X_train, y_train).predict(X_test)
    assert np.mean(ours == theirs) >= 0.995  # they may order equal distances differently


# --------------------------------------------------------------------------------------------
# k-means and bag of visual words
# --------------------------------------------------------------------------------------------
def _inertia(X, centers, labels):
    return float(np.sum((X - centers[labels]) ** 2))


@pytest.mark.parametrize("name", ["blobs", "uniform", "digits"])
def test_kmeans_inertia_within_one_percent_of_sklearn(name, digits):
    from sklearn.cluster import KMeans
    from sklearn.datasets import make_blobs

    X = {"blobs": lambda: make_blobs(1500, 8, centers=10, random_state=0)[0],
         "uniform": lambda: RNG.random((1500, 6)),
         "digits": lambda: digits[0][0]}[name]()
    k = 10
    ours = np.mean([_inertia(X, *learn.kmeans(X, k, rng=s)) for s in range(4)])
    theirs = np.mean([KMeans(k, n_init=1, random_state=s).fit(X).inertia_ for s in range(4)])
    assert ours <= 1.01 * theirs, (ours, theirs)


def test_kmeans_properties():
    X = RNG.normal(size=(200, 3))
    centers, labels = learn.kmeans(X, 6, rng=3)
    d = ((X[:, None] - centers[None]) ** 2).sum(-1)
    assert np.array_equal(labels, d.argmin(axis=1))
    for j in range(6):  # a fixed point of Lloyd's update
        assert np.allclose(centers[j], X[labels == j].mean(axis=0))
    again = learn.kmeans(X, 6, rng=3)
    assert np.array_equal(again[0], centers) and np.array_equal(again[1], labels)
    one_c, one_l = learn.kmeans(X, 1, rng=0)
    assert np.allclose(one_c[0], X.mean(axis=0)) and np.all(one_l == 0)


def test_kmeans_with_init_is_lloyd_and_reseeds_empty_clusters():
    X = np.array([[0.0, 0.0], [0.0, 1.0], [10.0, 10.0], [10.0, 11.0], [0.5, 0.5]])
    init = np.array([[0.0, 0.0], [100.0, 100.0]])
    # iteration 1: everything goes to centre 0, cluster 1 is empty and takes the farthest
    # sample from centre 0, (10, 11); the means are then (2.625, 2.875)... and (10, 11)
    c1, l1 = learn.kmeans(X, 2, iterations=1, init=init)
    assert np.allclose(c1, [[10.5 / 4, 11.5 / 4], [10.0, 11.0]])
    assert np.array_equal(l1, [0, 0, 1, 1, 0])  # the labels of the returned centres
    c, lab = learn.kmeans(X, 2, init=init)
    assert np.allclose(c, [[0.5 / 3, 1.5 / 3], [10.0, 10.5]])
    c0, l0 = learn.kmeans(X, 2, iterations=0, init=init)
    assert np.array_equal(c0, init) and np.all(l0 == 0)
    # two empty clusters: the farthest sample goes to the lower index
    c2, _ = learn.kmeans(X, 3, iterations=1, init=np.array([[0.0, 0.0], [99.0, 0.0], [0.0, 99.0]]))
    assert np.allclose(c2[1], [10.0, 11.0]) and np.allclose(c2[2], [10.0, 10.0])


def test_kmeans_refuses_more_clusters_than_distinct_points():
    X = np.repeat(np.eye(3), 4, axis=0)
    assert learn.kmeans(X, 3, rng=0)[0].shape == (3, 3)
    with pytest.raises(ValueError, match="distinct rows"):
        learn.kmeans(X, 4, rng=0)


@pytest.mark.parametrize("offset, spread", [(1e4, 1e-5), (255.0, 1e-5), (1e6, 1e-3), (0.0, 1.0)])
def test_kmeans_labels_are_exactly_the_nearest_returned_centres(offset, spread):
    # far from the origin, ‖x‖² − 2x·c + ‖c‖² loses the gaps between distances to round-off
    X = offset + spread * np.random.default_rng(3).normal(size=(200, 2))
    X_before = X.copy()
    for k in (2, 5):
        centers, labels = learn.kmeans(X, k, rng=0)
        exact = ((X[:, None, :] - centers[None, :, :]) ** 2).sum(axis=2)
        np.testing.assert_array_equal(labels, exact.argmin(axis=1))
        assert np.bincount(labels, minlength=k).min() >= 1  # no centre without its points
    np.testing.assert_array_equal(X, X_before)
    tiny = 1e6 + np.array([[0.0], [0.0004], [0.0007], [0.001]])
    _, labels = learn.kmeans(tiny, 2, iterations=0, init=np.array([[1e6], [1e6 + 0.001]]))
    np.testing.assert_array_equal(labels, [0, 0, 1, 1])


def test_bovw_histogram_matches_brute_force():
    codebook = RNG.normal(size=(7, 4))
    desc = RNG.normal(size=(50, 4))
    words = [int(np.argmin([np.sum((d - c) ** 2) for c in codebook])) for d in desc]
    counts = np.bincount(words, minlength=7).astype(float)
    assert np.array_equal(learn.bovw_histogram(desc, codebook, normalize=False), counts)
    assert np.allclose(learn.bovw_histogram(desc, codebook), counts / 50)
    tie = learn.bovw_histogram(np.array([[0.0]]), np.array([[1.0], [-1.0]]), normalize=False)
    assert tie.tolist() == [1.0, 0.0]  # equal distances: the lowest index


def test_dense_descriptors_against_a_loop_and_invariances():
    img = data.brick()[100:124, 200:232]
    d = learn.dense_descriptors(img, size=8, step=4, bins=8, cells=2)
    assert d.shape == (((24 - 8) // 4 + 1) * ((32 - 8) // 4 + 1), 32)
    # a loop version of the first window, before the SIFT normalisation
    gy, gx = np.gradient(img)
    hist = np.zeros((2, 2, 8))
    for r in range(8):
        for c in range(8):
            pos = (np.arctan2(gy[r, c], gx[r, c]) % (2 * np.pi)) * 8 / (2 * np.pi)
            lo = int(np.floor(pos)) % 8
            w = pos - np.floor(pos)
            mag = np.hypot(gx[r, c], gy[r, c])
            hist[r // 4, c // 4, lo] += mag * (1 - w)
            hist[r // 4, c // 4, (lo + 1) % 8] += mag * w
    v = hist.reshape(-1)
    v = np.minimum(v / np.linalg.norm(v), 0.2)
    keep_all = learn.dense_descriptors(img, min_gradient=0.0)
    assert np.allclose(keep_all[0], v / np.linalg.norm(v))
    assert np.allclose(learn.dense_descriptors(3.0 * img + 0.5, min_gradient=0.0), keep_all)  # contrast, brightness
    assert np.allclose(np.linalg.norm(keep_all, axis=1), 1.0)
    assert not learn.dense_descriptors(np.full((16, 16), 0.3)).any()  # flat: zero vectors
    # the contrast threshold: windows with a mean gradient magnitude below it are zero
    mean_gradient = np.array([np.hypot(gx, gy)[r:r + 8, c:c + 8].mean()
                              for r in range(0, 17, 4) for c in range(0, 25, 4)])
    assert np.array_equal(~d.any(axis=1), mean_gradient < 0.01)
    assert np.allclose(d[mean_gradient >= 0.01], keep_all[mean_gradient >= 0.01])


def test_bovw_texture_classification_target():
    (Xtr, ytr), (Xte, yte) = data.textures()
    desc_tr = [learn.dense_descriptors(p) for p in Xtr]
    desc_te = [learn.dense_descriptors(p) for p in Xte]
    pool = np.concatenate(desc_tr)
    sample = pool[np.random.default_rng(0).choice(len(pool), 8000, replace=False)]
    codebook, _ = learn.kmeans(sample, 64, rng=0)
    Htr = np.stack([learn.bovw_histogram(d, codebook) for d in desc_tr])
    Hte = np.stack([learn.bovw_histogram(d, codebook) for d in desc_te])
    W, b, _ = learn.sgd_train(Htr, ytr, 3, 1.0, 100, 16, rng=0)
    accuracy = np.mean(learn.linear_scores(Hte, W, b).argmax(axis=1) == yte)
    assert accuracy >= 0.9, accuracy


# --------------------------------------------------------------------------------------------
# inputs are never modified; bad input gives clear errors
# --------------------------------------------------------------------------------------------
def test_inputs_are_not_modified():
    X, y = RNG.normal(size=(20, 3)), RNG.integers(0, 3, 20)
    W, b = RNG.normal(size=(3, 3)), RNG.normal(size=3)
    arrays = [X, y, W, b]
    copies = [a.copy() for a in arrays]
    learn.linear_scores(X, W, b)
    learn.softmax(X)
    learn.cross_entropy(X, y)
    learn.linear_loss_and_grad(W, b, X, y, 0.1)
    learn.sgd_train(X, y, 3, 0.1, 2, 4, rng=0)
    learn.top_k_accuracy(X, y, 2)
    learn.knn_predict(X, y, X[:5], 3)
    learn.kmeans(X, 3, rng=0, init=X[:3])
    learn.bovw_histogram(X, W)
    assert all(np.array_equal(a, c) for a, c in zip(arrays, copies))


finite = st.floats(-1e3, 1e3, allow_nan=False)
SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(st.sampled_from([np.nan, np.inf]), st.integers(0, 5))
def test_non_finite_values_are_refused(bad, where):
    X = RNG.normal(size=(6, 3))
    X.flat[where] = bad
    y = np.array([0, 1, 2, 0, 1, 2])
    for call, name in [(lambda: learn.softmax(X), "scores"), (lambda: learn.cross_entropy(X, y), "scores"),
                       (lambda: learn.knn_predict(X, y, X), "X_train"), (lambda: learn.kmeans(X, 2, rng=0), "X"),
                       (lambda: learn.top_k_accuracy(X, y, 2), "scores"),
                       (lambda: learn.sgd_train(X, y, 3, 0.1, 1, 2), "X")]:
        with pytest.raises(ValueError, match=name):
            call()


@SETTINGS
@given(st.integers(1, 3).filter(lambda n: n != 2))
def test_wrong_dimensions_are_refused(ndim):
    arr = np.zeros((2,) * ndim)
    with pytest.raises(ValueError, match="X must have 2 dimensions"):
        learn.linear_scores(arr, np.zeros((2, 2)), np.zeros(2))
    with pytest.raises(ValueError, match="descriptors must have 2 dimensions"):
        learn.bovw_histogram(arr, np.zeros((2, 2)))
    if ndim == 3:
        with pytest.raises(ValueError, match="scores must have 1 or 2 dimensions"):
            learn.softmax(arr)


@SETTINGS
@given(st.integers(-3, 12), st.sampled_from(["float", "bool", "str", "neg"]))
def test_bad_labels_are_refused(value, kind):
    s = RNG.normal(size=(4, 3))
    y = np.array([0, 1, 2, 1])
    if kind == "float":
        y = y.astype(float)
        with pytest.raises(TypeError, match="y must be an integer array"):
            learn.cross_entropy(s, y)
    elif kind == "bool":
        with pytest.raises(TypeError, match="y_train"):
            learn.knn_predict(s, y.astype(bool), s)
    elif kind == "str":
        with pytest.raises(TypeError, match="y"):
            learn.top_k_accuracy(s, "0123")
    else:
        y = y.copy()
        y[0] = value
        if 0 <= value < 3:
            learn.cross_entropy(s, y)
        else:
            with pytest.raises(ValueError, match="y must contain labels"):
                learn.cross_entropy(s, y)


def test_labels_beyond_int64_are_refused_not_wrapped_around():
    """uint64 labels of 2**63 and more would turn negative as int64: refused, naming the
    argument (labels up to 2**63 − 1 still work)."""
    x = np.array([[0.0], [1.0]])
    with pytest.raises(ValueError, match="y_train must contain labels below 2\\*\\*63"):
        learn.knn_predict(x, np.array([2**63 + 5, 1], dtype=np.uint64), np.array([[0.1]]))
    assert learn.knn_predict(x, np.array([2**63 - 1, 1], dtype=np.uint64), np.array([[0.1]])).tolist() == [2**63 - 1]
    from cvkit.train import smooth_labels
    with pytest.raises(ValueError, match="below 2\\*\\*63"):
        smooth_labels(np.array([2.0**63, 0.0]), 3, 0.1)


@SETTINGS
@given(finite, st.integers(-2, 0))
def test_bad_hyperparameters_are_refused(lr, count):
    X, y = RNG.normal(size=(6, 2)), np.array([0, 1, 0, 1, 0, 1])
    with pytest.raises(ValueError, match="lr must be > 0" if lr <= 0 else "epochs"):
        learn.sgd_train(X, y, 2, lr if lr <= 0 else lr, count, 2)
    with pytest.raises(ValueError, match="batch_size must be >= 1"):
        learn.sgd_train(X, y, 2, 0.1, 1, count)
    with pytest.raises(ValueError, match="k must be >= 1"):
        learn.knn_predict(X, y, X, k=count)
    with pytest.raises(ValueError, match="k must be >= 1"):
        learn.kmeans(X, count)
    with pytest.raises(ValueError, match="eps must be > 0"):
        learn.numerical_gradient(np.sum, X, eps=float(count))


def test_mismatched_shapes_and_options_are_named():
    X, y = RNG.normal(size=(6, 3)), np.array([0, 1, 0, 1, 0, 1])
    cases = [
        (lambda: learn.linear_scores(X, np.zeros((2, 4)), np.zeros(2)), ValueError, "W must have one column"),
        (lambda: learn.linear_scores(X, np.zeros((2, 3)), np.zeros(3)), ValueError, "b must have one bias"),
        (lambda: learn.cross_entropy(X, y[:5]), ValueError, "y must have one label per row"),
        (lambda: learn.sgd_train(X, y, 1, 0.1, 1, 2), ValueError, "labels < 1"),
        (lambda: learn.knn_predict(X, y, np.zeros((2, 4))), ValueError, "X_test must have the 3 columns"),
        (lambda: learn.knn_predict(X, y, X, k=7), ValueError, "k must be at most the number of training"),
        (lambda: learn.knn_predict(X, y, X, metric="cosine"), ValueError, "metric must be one of"),
        (lambda: learn.kmeans(X, 2, init=np.zeros((3, 3))), ValueError, "init must have shape"),
        (lambda: learn.kmeans(X, 2, iterations=-1), ValueError, "iterations must be >= 0"),
        (lambda: learn.kmeans(X, 2, rng="seed"), TypeError, "rng must be"),
        (lambda: learn.bovw_histogram(X, np.zeros((2, 4))), ValueError, "codebook must have the 3 columns"),
        (lambda: learn.bovw_histogram(X, np.zeros((2, 3)), normalize="yes"), TypeError, "normalize"),
        (lambda: learn.bovw_histogram(np.zeros((0, 3)), np.zeros((2, 3))), ValueError, "descriptors must not be empty"),
        (lambda: learn.dense_descriptors(np.zeros((4, 4)), size=8), ValueError, "image must be at least"),
        (lambda: learn.dense_descriptors(np.zeros((16, 16)), size=9, cells=2), ValueError, "multiple of cells"),
        (lambda: learn.top_k_accuracy(X, y, k=1.5), TypeError, "k must be an integer"),
    ]
    for call, error, message in cases:
        with pytest.raises(error, match=message):
            call()
