# Answer cells of the "typical mistakes" sample submission of ch10_representations.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution. (The first half of the chapter has three exercises: two typical mistakes and one
# exercise left unattempted.)
# This file is data for the demo and its tests, not a module to import.

# %% knn_predict_answer
@student("learn.knn_predict")
def knn_predict(X_train, y_train, X_test, k=1, metric="l2"):
    """kNN with Counter.most_common for the vote, which gives a tie to the label met first."""
    from collections import Counter

    A = np.asarray(X_train, dtype=float)
    out = []
    for q in np.asarray(X_test, dtype=float):
        diff = A - q
        d = np.sum(diff ** 2, axis=1) if metric == "l2" else np.sum(np.abs(diff), axis=1)
        nearest = np.argsort(d, kind="stable")[:k]
        out.append(Counter(np.asarray(y_train)[nearest].tolist()).most_common(1)[0][0])
    return np.array(out)

# %% kmeans_answer
@student("learn.kmeans")
def kmeans(X, k, iterations=50, rng=None, init=None):
    """k-means++ and Lloyd's loop, but an empty cluster's mean is np.mean of nothing: NaN."""
    X = np.asarray(X, dtype=float)
    generator = np.random.default_rng(rng)
    n = len(X)
    if init is not None:
        centers = np.array(init, dtype=float)
    else:
        centers = [X[generator.integers(n)]]
        closest = np.sum((X - centers[0]) ** 2, axis=1)
        for _ in range(1, k):
            pick = generator.choice(n, p=closest / closest.sum())
            centers.append(X[pick])
            closest = np.minimum(closest, np.sum((X - X[pick]) ** 2, axis=1))
        centers = np.array(centers)
    labels = np.argmin(np.sum((X[:, None] - centers[None]) ** 2, axis=2), axis=1)
    for _ in range(iterations):
        with np.errstate(invalid="ignore"):
            new = np.array([X[labels == j].mean(axis=0) if np.any(labels == j) else np.full(X.shape[1], np.nan)
                            for j in range(k)])
        if np.array_equal(new, centers, equal_nan=True):
            break
        centers = new
        with np.errstate(invalid="ignore"):
            labels = np.argmin(np.sum((X[:, None] - centers[None]) ** 2, axis=2), axis=1)
    return centers, labels

# %% bovw_histogram_answer
@student("learn.bovw_histogram")
def bovw_histogram(descriptors, codebook, normalize=True):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
