"""Independent references for rods clamped at both ends (pure numpy/scipy).

Like ``tests/references.py``, nothing here imports jax or sorojax: the equations are
written from the mechanics directly, so that they can judge sorojax's solutions.

Model: the geometrically exact (Simo-Reissner) rod, weightless, unloaded between its
ends. Arc length ``s in [0, L]``, centre line ``p(s)``, section rotation ``R(s)``;
body strains ``u = (R^T R')^vee`` (torsion, bend y, bend z) and ``v = R^T p'``
(``(1, 0, 0)`` unstrained); linear elastic ``m = diag(GJ, EIy, EIz) u``,
``n = diag(EA, GAy, GAz) (v - (1, 0, 0))`` in the body frame. In the world frame the
internal force ``N = R n`` is constant and the moment ``M = R m`` obeys
``M' = -p' x N``. Both ends are clamped: ``p(0) = 0``, ``R(0) = I``, and the far end
at a given pose. ``scipy.integrate.solve_bvp`` (global collocation) solves the two-
point problem to ``tol`` from a guess.

Contents:
    planar_clamped_clamped  -- a rod clamped at both ends, the far end on the x axis
                               at distance ``d`` (buckled when ``d < L``), in x-y
    clamped_at_pose         -- a rod whose far end is clamped at any pose (3D)
    twisted_end_pose        -- the out-of-plane, twisted far-end pose of the
                               adequacy tests and benchmark
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_bvp

__all__ = ["planar_clamped_clamped", "clamped_at_pose", "twisted_end_pose"]


def planar_clamped_clamped(L, d, EI, EA, GA, *, n_mesh=400, tol=1e-10):
    """A planar rod clamped at ``(0, 0)`` and at ``(d, 0)``, both tangents along x.

    Unknowns ``y = (x, y, theta, m, N_x, N_y)`` (``N`` constant): ``theta' = m / EI``,
    ``m' = -(x' N_y - y' N_x)``, ``(x', y') = R(theta) (1 + n_1 / EA, n_2 / GA)`` with
    ``(n_1, n_2) = R(theta)^T N``. The guess is the first clamped-clamped buckling
    mode ``w = a/2 (1 - cos(2 pi s / L))`` with the inextensible amplitude
    ``a = 2 sqrt(L (L - d)) / pi`` (bending towards +y) and Euler's load
    ``N_x = -4 pi^2 EI / L^2``: the solution is the symmetric buckled shape.

    Args:
        L: rod length [m]; d: end distance [m]; EI, EA, GA: bending, axial and
        shear stiffnesses [N m^2, N, N].
        n_mesh: initial collocation mesh; tol: solve_bvp's tolerance.

    Returns:
        ``(positions, sol)``: ``positions(s) -> (len(s), 3)`` world centre line
        [m] (z = 0) and scipy's solution object.

    Raises:
        RuntimeError: solve_bvp did not converge.
    """
    # dimensionless: lengths / L, moments / (EI / L), forces / (EI / L^2)
    ea, ga = EA * L**2 / EI, GA * L**2 / EI
    s = np.linspace(0.0, 1.0, n_mesh)
    k = 2.0 * math.pi
    a = 2.0 * math.sqrt(max(1.0 - d / L, 0.0)) / math.pi
    guess = np.stack(
        [
            s * d / L,
            a / 2.0 * (1.0 - np.cos(k * s)),
            a / 2.0 * k * np.sin(k * s),
            a / 2.0 * k**2 * np.cos(k * s),
            np.full_like(s, -(k**2)),
            np.zeros_like(s),
        ]
    )

    def rhs(_, y):
        c, sn = np.cos(y[2]), np.sin(y[2])
        n1 = c * y[4] + sn * y[5]
        n2 = -sn * y[4] + c * y[5]
        v1, v2 = 1.0 + n1 / ea, n2 / ga
        dx, dy = c * v1 - sn * v2, sn * v1 + c * v2
        z = np.zeros_like(y[0])
        return np.stack([dx, dy, y[3], -(dx * y[5] - dy * y[4]), z, z])

    def bc(ya, yb):
        return np.array([ya[0], ya[1], ya[2], yb[0] - d / L, yb[1], yb[2]])

    sol = solve_bvp(rhs, bc, s, guess, tol=tol, max_nodes=200000)
    if not sol.success:
        raise RuntimeError(f"planar_clamped_clamped: solve_bvp failed: {sol.message}")

    def positions(si):
        y = sol.sol(np.asarray(si, dtype=float) / L)
        return L * np.stack([y[0], y[1], np.zeros_like(y[0])], axis=-1)

    return positions, sol


def clamped_at_pose(L, stiffness, g_end, s_guess, g_guess, wrench_guess, *, tol=1e-10):
    """A rod clamped at the origin (``R = I``) and at the world pose ``g_end``.

    Unknowns per point: ``p`` (3), ``R`` (9, row-major), ``M`` (3), ``N`` (3), all
    world frame: ``p' = R v``, ``R' = R hat(u)``, ``M' = -p' x N``, ``N' = 0``, with
    ``u = K_b^-1 R^T M`` and ``v = (1, 0, 0) + K_s^-1 R^T N``. Boundary rows:
    ``p(0) = 0``, ``R(0) = I`` (12), ``p(L) = p_end`` and the skew part of
    ``R_end^T R(L)`` (3).

    Args:
        L: rod length [m].
        stiffness: ``(GJ, EIy, EIz, EA, GAy, GAz)``.
        g_end: ``(4, 4)`` world pose of the far clamp.
        s_guess: ``(n,)`` arc lengths of the guess, from 0 to L.
        g_guess: ``(n, 4, 4)`` guessed poses there.
        wrench_guess: ``(n, 6)`` guessed world internal ``(M, N)`` there.
        tol: solve_bvp's tolerance.

    Returns:
        ``(positions, sol)``: ``positions(s) -> (len(s), 3)`` [m] and scipy's
        solution object.

    Raises:
        RuntimeError: solve_bvp did not converge.
    """
    # dimensionless: lengths / L, moments / (EI / L), forces / (EI / L^2)
    EI = float(stiffness[2])
    Kb = np.asarray(stiffness[:3], dtype=float) / EI
    Ks = np.asarray(stiffness[3:], dtype=float) * L**2 / EI
    g_end = np.asarray(g_end, dtype=float)
    g_guess = np.asarray(g_guess, dtype=float)
    w = np.asarray(wrench_guess, dtype=float)
    guess = np.concatenate(
        [
            g_guess[:, :3, 3].T / L,
            g_guess[:, :3, :3].reshape(len(s_guess), 9).T,
            w[:, :3].T * L / EI,
            w[:, 3:].T * L**2 / EI,
        ]
    )

    def rhs(_, y):
        R = y[3:12].T.reshape(-1, 3, 3)
        M, N = y[12:15].T, y[15:18].T
        u = np.einsum("nji,nj->ni", R, M) / Kb
        v = np.einsum("nji,nj->ni", R, N) / Ks
        v[:, 0] += 1.0
        dp = np.einsum("nij,nj->ni", R, v)
        hu = np.zeros((len(u), 3, 3))
        hu[:, 0, 1], hu[:, 0, 2], hu[:, 1, 2] = -u[:, 2], u[:, 1], -u[:, 0]
        hu[:, 1, 0], hu[:, 2, 0], hu[:, 2, 1] = u[:, 2], -u[:, 1], u[:, 0]
        dR = R @ hu
        dM = -np.cross(dp, N)
        return np.concatenate(
            [dp.T, dR.reshape(-1, 9).T, dM.T, np.zeros_like(N.T)], axis=0
        )

    def bc(ya, yb):
        Rb = yb[3:12].reshape(3, 3)
        E = g_end[:3, :3].T @ Rb
        skew = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
        return np.concatenate(
            [ya[0:3], ya[3:12] - np.eye(3).ravel(), yb[0:3] - g_end[:3, 3] / L, skew]
        )

    s = np.asarray(s_guess, dtype=float) / L
    sol = solve_bvp(rhs, bc, s, guess, tol=tol, max_nodes=200000)
    if not sol.success:
        raise RuntimeError(f"clamped_at_pose: solve_bvp failed: {sol.message}")

    def positions(si):
        return L * sol.sol(np.asarray(si, dtype=float) / L)[0:3].T

    return positions, sol


def twisted_end_pose(L: float) -> np.ndarray:
    """The far end at (0.6, 0.3, 0.25) L, turned Rz(0.5) Ry(-0.6) Rx(1.2): (4, 4)."""

    def rot(axis, angle):
        c, s = math.cos(angle), math.sin(angle)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        m = np.eye(3)
        m[i, i] = m[j, j] = c
        m[i, j], m[j, i] = -s, s
        return m

    g = np.eye(4)
    g[:3, :3] = rot(2, 0.5) @ rot(1, -0.6) @ rot(0, 1.2)
    g[:3, 3] = np.array([0.6, 0.3, 0.25]) * L
    return g
