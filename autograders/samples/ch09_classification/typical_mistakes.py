# Answer cells of the "typical mistakes" sample submission of ch09_classification.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution. The loss with the wrong regularisation gradient also sinks the SGD exercise that
# would build on it, had it been attempted (it is left unattempted here).
# This file is data for the demo and its tests, not a module to import.

# %% top_k_accuracy_answer
@student("learn.top_k_accuracy")
def top_k_accuracy(scores, y, k=5):
    """Top-k accuracy -- but argsort sorts in increasing order: these are the k LOWEST scores."""
    scores = np.asarray(scores, dtype=float)
    top = np.argsort(scores, axis=1)[:, :k]
    return float(np.mean(np.any(top == np.asarray(y)[:, None], axis=1)))

# %% softmax_answer
@student("learn.softmax")
def softmax(scores):
    """The textbook formula, without subtracting the maximum first."""
    e = np.exp(np.asarray(scores, dtype=float))
    return e / e.sum(axis=-1, keepdims=True)

# %% linear_loss_and_grad_answer
@student("learn.linear_loss_and_grad")
def linear_loss_and_grad(W, b, X, y, reg=0.0):
    """Loss and gradients -- the derivative of reg * sum(W**2) taken as reg * W."""
    W = np.asarray(W, dtype=float)
    X = np.asarray(X, dtype=float)
    loss, dscores = cross_entropy(linear_scores(X, W, b), y)
    return loss + reg * np.sum(W * W), dscores.T @ X + reg * W, dscores.sum(axis=0)

# %% numerical_gradient_answer
@student("learn.numerical_gradient")
def numerical_gradient(f, x, eps=1e-5):
    """A one-sided difference (f(x + h) - f(x)) / h: only first-order accurate."""
    x = np.array(x, dtype=float)
    grad = np.zeros_like(x)
    fx = f(x)
    for index in np.ndindex(x.shape):
        old = x[index]
        x[index] = old + eps
        grad[index] = (f(x) - fx) / eps
        x[index] = old
    return grad

# %% sgd_train_answer
@student("learn.sgd_train")
def sgd_train(X, y, classes, lr, epochs, batch_size, reg=0.0, rng=None):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()

# %% train_digit_classifier_answer
@student("learn.train_digit_classifier")
def train_digit_classifier(x_train, y_train, rng=None):
    """A linear classifier -- whose labels come out as 1..10 instead of 0..9."""
    X = np.asarray(x_train, dtype=np.float64).reshape(len(x_train), -1)
    mean, spread = X.mean(), X.std()
    W, b, _ = sgd_train((X - mean) / spread, np.asarray(y_train), 10, 0.1, 30, 32, reg=1e-3, rng=rng)
    return lambda x: np.argmax(linear_scores((np.asarray(x, float).reshape(len(x), -1) - mean) / spread, W, b), axis=1) + 1
