"""Gradient of Fitness (Eq. 10) with respect to every point of a window (Sec. 4.2.4, Eq. 20-27).

Two routes, switchable in NACOA: the exact analytic gradient (Eq. 21-22 worked out by the chain rule,
plus the gradient of the norm in Eq. 9) and the paper's central difference (Eq. 23).  Both return an
array shaped like the points, (..., n, 2); rows of the two end points are zero, since they never move.

Eq. 24 in the paper, ``4 P_i - 2 P_{i-1} - 2 P_{i+1}``, is the gradient of half the *squared* second
difference with respect to its centre point only; the smoothness term of Eq. 9 is the plain norm, so
the exact route differentiates the norm (all three points of every term) instead.  The difference is
listed in the report.
"""

from __future__ import annotations

import numpy as np


def fitness_gradient(points: np.ndarray) -> np.ndarray:
    """Exact gradient of Eq. 10 (LocalCurvature + SmoothnessPenalty) at ``points`` (..., n, 2).

    With ``a = v_{j-1}``, ``b = v_j`` and ``c = cos(a, b)`` (Eq. 22):
    ``dc/da = b / (|a||b|) - c a / |a|^2`` and ``dc/db = a / (|a||b|) - c b / |b|^2``; the turning
    term ``1 - c`` (Eq. 21) then pushes ``-dc/da`` onto ``P_{j-1}``, ``dc/db - dc/da`` ... onto the three
    points through ``a = P_j - P_{j-1}`` and ``b = P_{j+1} - P_j``.  A zero-length segment contributes
    nothing (its term counts as no turn, as in :func:`toolpath.geometry.curvature.turning_cosines`).
    """
    p = np.asarray(points, dtype=np.float64)
    # written per coordinate (x, y): NACOA calls this on the whole population every generation
    vx, vy = np.diff(p[..., 0], axis=-1), np.diff(p[..., 1], axis=-1)
    ax, ay, bx, by = vx[..., :-1], vy[..., :-1], vx[..., 1:], vy[..., 1:]
    na2, nb2 = ax * ax + ay * ay, bx * bx + by * by
    ok = (na2 > 0) & (nb2 > 0)
    na2, nb2 = np.where(ok, na2, 1.0), np.where(ok, nb2, 1.0)
    inv_ab = np.where(ok, 1.0 / np.sqrt(na2 * nb2), 0.0)
    c = (ax * bx + ay * by) * inv_ab
    ca, cb = c / na2, c / nb2
    dax, day = bx * inv_ab - ca * ax, by * inv_ab - ca * ay  # dc/da
    dbx, dby = ax * inv_ab - cb * bx, ay * inv_ab - cb * by  # dc/db
    # second_diff_j = |P_{j+1} - 2 P_j + P_{j-1}| (Eq. 9): unit vector u to P_{j-1}, P_{j+1}; -2u to P_j
    sx, sy = bx - ax, by - ay
    ns = np.sqrt(sx * sx + sy * sy)
    # the norm has a kink at 0; below rounding noise of the segments take its subgradient 0
    kink = ns <= 1e-12 * (np.sqrt(na2) + np.sqrt(nb2))
    inv_s = np.where(kink, 0.0, 1.0 / np.where(kink, 1.0, ns))
    ux, uy = sx * inv_s, sy * inv_s
    grad = np.zeros_like(p)
    # curvature_j = 1 - c_j: d/dP_{j-1} = +dc/da, d/dP_j = dc/db - dc/da, d/dP_{j+1} = -dc/db
    for k, (da, db, u) in enumerate(((dax, dbx, ux), (day, dby, uy))):
        grad[..., :-2, k] += da + u
        grad[..., 1:-1, k] += db - da - 2.0 * u
        grad[..., 2:, k] -= db - u
    grad[..., 0, :] = 0.0
    grad[..., -1, :] = 0.0
    return grad


def _stencil_terms(stencil: np.ndarray) -> np.ndarray:
    """Eq. 6 + Eq. 9 terms centred at stencil positions 1, 2, 3 of 5-point stencils, shape (..., 3)."""
    from toolpath.geometry.curvature import turning_cosines

    second = stencil[..., 2:, :] - 2.0 * stencil[..., 1:-1, :] + stencil[..., :-2, :]
    return 1.0 - turning_cosines(stencil) + np.linalg.norm(second, axis=-1)


def central_difference_gradient(points: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    """The paper's numerical gradient, Eq. 23: ``(F(P + eps e) - F(P - eps e)) / (2 eps)`` per coordinate.

    Moving interior point ``j`` changes only the terms centred at ``j - 1``, ``j`` and ``j + 1``, so
    each difference is taken on the 5-point stencil around ``j``, dropping the terms centred on an end
    point (they do not exist in Eq. 10): the same number as differencing the whole Eq. 10, at a
    fraction of the cost.  ``eps`` in (1e-6, 1e-4) as the paper says.
    """
    p = np.asarray(points, dtype=np.float64)
    n = p.shape[-2]
    padded = np.concatenate([p[..., :1, :], p, p[..., -1:, :]], axis=-2)
    # padded row r holds point r - 1; the stencil of interior point j = k + 1 is rows k .. k + 4
    stencil = padded[..., np.arange(n - 2)[:, None] + np.arange(5)[None, :], :]  # (..., n-2, 5, 2)
    centres = np.arange(1, n - 1)[:, None] + np.arange(-1, 2)[None, :]
    exists = (centres >= 1) & (centres <= n - 2)  # (n-2, 3)
    grad = np.zeros_like(p)
    for axis in (0, 1):
        plus, minus = stencil.copy(), stencil.copy()
        plus[..., 2, axis] += eps
        minus[..., 2, axis] -= eps
        diff = np.where(exists, _stencil_terms(plus) - _stencil_terms(minus), 0.0).sum(axis=-1)
        grad[..., 1:-1, axis] = diff / (2.0 * eps)
    return grad
