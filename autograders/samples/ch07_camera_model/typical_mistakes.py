# Answer cells of the "typical mistakes" sample submission of ch07_camera_model.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Every other exercise keeps the correct
# solution, so the feedback shows what the checks recognise (and how one wrong building
# block, `from_homogeneous` here, also costs hidden cases of `project`, which calls it).
# This file is data for the demo and its tests, not a module to import.

# %% rotation_matrix_answer
@student("camera.rotation_matrix")
def rotation_matrix(roll, pitch, yaw):
    """Roll, pitch, yaw -- multiplied in the order they are named, which reverses the rotations."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz

# %% from_homogeneous_answer
@student("camera.from_homogeneous")
def from_homogeneous(points_h):
    """Divides by w -- but 'protects' the points at infinity by writing 0 there."""
    points_h = np.asarray(points_h, dtype=float)
    w = np.broadcast_to(points_h[..., -1:], points_h[..., :-1].shape)
    return np.divide(points_h[..., :-1], w, out=np.zeros(w.shape), where=w != 0)

# %% decompose_projection_answer
@student("camera.decompose_projection")
def decompose_projection(P):
    """scipy's RQ decomposition used as it comes: nobody checks the signs of the diagonal."""
    import scipy.linalg

    P = np.asarray(P, dtype=float)
    M, p4 = P[:, :3], P[:, 3]
    if np.linalg.det(M) < 0:
        M, p4 = -M, -p4
    K, R = scipy.linalg.rq(M)
    t = np.linalg.solve(K, p4)
    return K / K[2, 2], R, t

# %% distort_answer
@student("camera.distort")
def distort(xy_normalized, k=(0.0, 0.0, 0.0), p=(0.0, 0.0)):
    """Radial and tangential distortion with p1 and p2 exchanged."""
    xy = np.asarray(xy_normalized, dtype=float)
    k = list(np.atleast_1d(k)) + [0.0, 0.0]
    p1, p2 = p
    x, y = xy[:, 0], xy[:, 1]
    r2 = x**2 + y**2
    radial = 1 + k[0] * r2 + k[1] * r2**2 + k[2] * r2**3
    x_d = x * radial + 2 * p2 * x * y + p1 * (r2 + 2 * x**2)
    y_d = y * radial + p2 * (r2 + 2 * y**2) + 2 * p1 * x * y
    return np.column_stack([x_d, y_d])

# %% undistort_points_answer
@student("camera.undistort_points")
def undistort_points(xy_distorted, k, p, iterations=20):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()

# %% project_full_answer
@student("camera.project_full")
def project_full(points_world, A, R, t, k=(0.0, 0.0, 0.0), p=(0.0, 0.0)):
    """The four steps -- with the lens distortion applied to the pixels, after A."""
    X = np.asarray(points_world, dtype=float)
    A = np.asarray(A, dtype=float)
    cam = X @ np.asarray(R, dtype=float).T + np.asarray(t, dtype=float).reshape(3)
    uv = from_homogeneous(to_homogeneous(cam[:, :2] / cam[:, 2:]) @ A.T)
    k = list(np.atleast_1d(k)) + [0.0, 0.0]
    p1, p2 = p
    u, v = uv[:, 0], uv[:, 1]
    r2 = u**2 + v**2
    radial = 1 + k[0] * r2 + k[1] * r2**2 + k[2] * r2**3
    return np.column_stack([u * radial + 2 * p1 * u * v + p2 * (r2 + 2 * u**2),
                            v * radial + p1 * (r2 + 2 * v**2) + 2 * p2 * u * v])
