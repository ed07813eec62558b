"""Feedrate limits from curvature (the NURBS corner paper, Eq. 15-22).

Every limit is a function of the radius of curvature rho (mm; ``inf`` on a straight line) and
returns mm/s.  Machine values (the NURBS corner paper's Table 1 was lost from its text) come from
``conf/feedrate/``, where each default says where it comes from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Machine:
    """Limits of one machine and controller (mm, s)."""

    feed: float              # programmed feedrate v_p, mm/s
    period: float            # interpolation period T, s
    chord_error: float       # Delta_lim, mm
    contour_error: float     # epsilon_lim, mm
    normal_acceleration: float  # a_n,lim, mm/s^2
    normal_jerk: float       # j_n,lim, mm/s^3
    tangential_acceleration: float  # a_t,lim, mm/s^2
    tangential_jerk: float   # j_t,lim, mm/s^3
    kp: float                # position-loop proportional gain K_p
    inertia: float           # equivalent rotational inertia J of the feed drive
    damping: float           # equivalent damping B

    @property
    def natural_frequency(self) -> float:
        """w_n = sqrt(K_p / J) (Eq. 17)."""
        return float(np.sqrt(self.kp / self.inertia))

    @property
    def damping_ratio(self) -> float:
        """zeta = B / (2 sqrt(J K_p)) (Eq. 17)."""
        return float(self.damping / (2.0 * np.sqrt(self.inertia * self.kp)))


def chord_error_limit(rho: np.ndarray, machine: Machine) -> np.ndarray:
    """v_Delta = 2 sqrt(2 rho Delta - Delta^2) / T (Eq. 16); inf where rho is inf.

    Where rho <= Delta the chord error (at most rho, the sagitta of a half circle) cannot exceed the
    limit, and Eq. 15 holds only while the chord vT is no longer than the diameter: v = 2 rho / T
    there (equal to Eq. 16 at rho = Delta, so the limit is continuous; Eq. 16 alone would fall to 0
    below rho = Delta / 2 and stop the tool on any tiny radius)."""
    rho = np.asarray(rho, dtype=float)
    d = machine.chord_error
    with np.errstate(invalid="ignore"):
        v = 2.0 * np.sqrt(np.maximum(2.0 * rho * d - d * d, 0.0)) / machine.period
    v = np.where(rho <= d, 2.0 * rho / machine.period, v)
    return np.where(np.isinf(rho), np.inf, v)


def chord_error(v: np.ndarray, rho: np.ndarray, period: float) -> np.ndarray:
    """Delta = rho - sqrt(rho^2 - (vT/2)^2) (Eq. 15), in the cancellation-free form; 0 on a line."""
    v, rho = np.asarray(v, dtype=float), np.asarray(rho, dtype=float)
    half = (v * period / 2.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        delta = half / (rho + np.sqrt(np.maximum(rho * rho - half, 0.0)))
    return np.where(np.isinf(rho), 0.0, delta)


def contour_error_limit(rho: np.ndarray, machine: Machine) -> np.ndarray:
    """v_c of Eq. 17 (second-order servo model of the feed drive); inf where rho is inf.

    Where ``rho <= epsilon_lim`` the radius itself is inside the tolerance and the limit does not bind.
    """
    rho = np.asarray(rho, dtype=float)
    eps, wn, zeta = machine.contour_error, machine.natural_frequency, machine.damping_ratio
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        inner = (2 * zeta**2 - 1) ** 2 - (eps**2 - 2 * eps * rho) / (rho - eps) ** 2
        v = rho * wn * np.sqrt(np.maximum(1 - 2 * zeta**2 + np.sqrt(np.maximum(inner, 0.0)), 0.0))
    return np.where(np.isinf(rho) | (rho <= eps), np.inf, v)


def normal_acceleration_limit(rho: np.ndarray, machine: Machine) -> np.ndarray:
    """v_a = sqrt(rho a_n,lim) (Eq. 19)."""
    return np.sqrt(np.asarray(rho, dtype=float) * machine.normal_acceleration)


def normal_jerk_limit(rho: np.ndarray, machine: Machine) -> np.ndarray:
    """v_j = cbrt(rho^2 j_n,lim) (Eq. 21, from j_n = v^3 / rho^2 of Eq. 20)."""
    return np.cbrt(np.asarray(rho, dtype=float) ** 2 * machine.normal_jerk)


def feed_limit(rho: np.ndarray, machine: Machine) -> np.ndarray:
    """v_f = min(v_Delta, v_a, v_j, v_c) (Eq. 22), capped at the programmed feed."""
    return np.minimum.reduce([chord_error_limit(rho, machine), contour_error_limit(rho, machine),
                              normal_acceleration_limit(rho, machine), normal_jerk_limit(rho, machine),
                              np.full(np.shape(rho), machine.feed)])


def polyline_radius(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Radius of curvature at each vertex of a G01 polyline (mm; inf at the ends and on straight runs).

    A controller blends each corner with an arc; we take the largest arc that stays within
    ``tolerance`` of the corner and whose tangent points lie within half of each adjacent segment:
    for a turn of theta between segments of lengths l1, l2,
    ``rho = min(tol cos(theta/2) / (1 - cos(theta/2)), min(l1, l2) / 2 / tan(theta/2))``.
    On a circle of radius R cut into k chords this gives R cos(pi/k), so a finely discretised
    smooth curve keeps its own curvature; a sharp corner gets the small radius a blend allows.
    """
    points = np.asarray(points, dtype=float)
    rho = np.full(len(points), np.inf)
    if len(points) < 3:
        return rho
    seg = np.diff(points, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    a, b = seg[:-1], seg[1:]
    la, lb = length[:-1], length[1:]
    ok = (la > 0) & (lb > 0)
    cos_turn = np.where(ok, (a * b).sum(axis=1) / np.where(ok, la * lb, 1.0), 1.0)
    theta = np.arccos(np.clip(cos_turn, -1.0, 1.0))
    half = theta / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        by_tolerance = tolerance * np.cos(half) / (1.0 - np.cos(half))
        by_length = np.minimum(la, lb) / 2.0 / np.tan(half)
    inner = np.where(ok & (theta > 1e-12), np.minimum(by_tolerance, by_length), np.inf)
    rho[1:-1] = inner
    return rho
