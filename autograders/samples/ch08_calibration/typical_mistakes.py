# Answer cells of the "typical mistakes" sample submission of ch08_calibration.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution, so the feedback shows what the checks recognise (and how one wrong building
# block, `levenberg_marquardt` here, can also cost hidden cases of the exercises that call it).
# This file is data for the demo and its tests, not a module to import.

# %% homography_dlt_answer
@student("calibration.homography_dlt")
def homography_dlt(src, dst, normalize=True):
    """The DLT straight from the notes: two rows per point, SVD -- on the raw pixels."""
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    rows = []
    for (x, y), (u, v) in zip(src, dst):
        rows.append([x, y, 1, 0, 0, 0, -u * x, -u * y, -u])
        rows.append([0, 0, 0, x, y, 1, -v * x, -v * y, -v])
    _, _, Vt = np.linalg.svd(np.array(rows))
    H = Vt[-1].reshape(3, 3)
    return H / H[2, 2]

# %% levenberg_marquardt_answer
@student("calibration.levenberg_marquardt")
def levenberg_marquardt(residuals, x0, jacobian=None, max_iter=100, tol=1e-10):
    """A careful LM -- that reports the sum of squares as the cost."""
    x = np.array(x0, dtype=float)

    def jac(x, r):
        if jacobian is not None:
            return np.asarray(jacobian(x.copy()), dtype=float)
        J = np.zeros((r.size, x.size))
        for j in range(x.size):
            h = 1e-7 * max(1.0, abs(x[j]))
            xh = x.copy()
            xh[j] += h
            J[:, j] = (np.ravel(residuals(xh)) - r) / h
        return J

    r = np.ravel(residuals(x.copy())).astype(float)
    J = jac(x, r)
    mu, it, done = 1e-3, 0, np.abs(J.T @ r).max() <= tol
    while not done and it < max_iter:
        it += 1
        A = J.T @ J
        step = np.linalg.solve(A + mu * np.diag(np.maximum(np.diag(A), 1e-12)), -J.T @ r)
        r_new = np.ravel(residuals(x + step)).astype(float)
        if r_new @ r_new < r @ r:
            done = (r @ r - r_new @ r_new) < tol * (r @ r) or np.linalg.norm(step) <= tol * (np.linalg.norm(x) + tol)
            x, r, mu = x + step, r_new, mu / 10
            J = jac(x, r)
            done = done or np.abs(J.T @ r).max() <= tol
        else:
            mu *= 10
            done = np.linalg.norm(step) <= tol * (np.linalg.norm(x) + tol)
    return x, {"iterations": it, "cost": float(r @ r), "converged": bool(done)}

# %% extrinsics_from_homography_answer
@student("calibration.extrinsics_from_homography")
def extrinsics_from_homography(A, H):
    """r1, r2, t from A⁻¹H, r3 = r1 × r2 -- and that is taken as the rotation."""
    M = np.linalg.inv(np.asarray(A, dtype=float)) @ np.asarray(H, dtype=float)
    lam = 1 / np.linalg.norm(M[:, 0])
    if M[2, 2] * lam < 0:
        lam = -lam
    r1, r2, t = lam * M[:, 0], lam * M[:, 1], lam * M[:, 2]
    return np.column_stack([r1, r2, np.cross(r1, r2)]), t

# %% bilinear_sample_answer
@student("warp.bilinear_sample")
def bilinear_sample(image, x, y, fill=0.0):
    """Bilinear interpolation whose inside test stops short of the last row and column."""
    img = np.asarray(image, dtype=float)
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    H, W = img.shape[:2]
    inside = (x >= 0) & (x < W - 1) & (y >= 0) & (y < H - 1)
    xs, ys = np.where(inside, x, 0), np.where(inside, y, 0)
    x0, y0 = np.floor(xs).astype(int), np.floor(ys).astype(int)
    a, b = xs - x0, ys - y0
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    if img.ndim == 3:
        a, b, inside = a[..., None], b[..., None], inside[..., None]
    value = ((1 - a) * (1 - b) * img[y0, x0] + a * (1 - b) * img[y0, x1]
             + (1 - a) * b * img[y1, x0] + a * b * img[y1, x1])
    return np.where(inside, value, fill)

# %% warp_homography_answer
@student("warp.warp_homography")
def warp_homography(image, H, output_shape, fill=0.0):
    """Backward mapping -- through H itself instead of its inverse."""
    H = np.asarray(H, dtype=float)
    rows, cols = output_shape
    xs, ys = np.meshgrid(np.arange(cols), np.arange(rows))
    m = H @ np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    return bilinear_sample(image, (m[0] / m[2]).reshape(rows, cols), (m[1] / m[2]).reshape(rows, cols), fill)

# %% rotation_homography_answer
@student("warp.rotation_homography")
def rotation_homography(A, R):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
