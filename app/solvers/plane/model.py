"""The xyz_plane model: touches on labelled planes, the packed unknowns, the signed distances of
the tips from their planes and their Jacobian in the planes' tangent coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.arrays import FloatArray


@dataclass(frozen=True)
class PlaneTouches:
    R: FloatArray  # (N, 3, 3)
    f: FloatArray  # (N, 3)
    plane: NDArray[np.intp]  # (N,) index into labels
    labels: tuple[str, ...]


def unpack(x: FloatArray, k: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """x = [t (3), then per plane (nx, ny, nz, d)] -> t, normals (K, 3) unit, offsets (K,)."""
    t = x[:3]
    rest = x[3:].reshape(k, 4)
    normals = rest[:, :3] / np.linalg.norm(rest[:, :3], axis=1, keepdims=True)
    return t, normals, rest[:, 3]


def signed_distances(
    touches: PlaneTouches, t: FloatArray, normals: FloatArray, offsets: FloatArray
) -> FloatArray:
    """Signed distance (mm) of each tip from its plane."""
    tips = touches.f + touches.R @ t
    n = normals[touches.plane]
    out: FloatArray = np.einsum("ij,ij->i", n, tips) - offsets[touches.plane]
    return out


def tangents(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors completing `normal` to a right-handed orthonormal basis."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    e1 = cross3(normal, helper)
    e1 /= np.linalg.norm(e1)
    return e1, cross3(normal, e1)


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b of two 3-vectors: np.cross's products and differences, without its overhead."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def distance_jacobian(touches: PlaneTouches, t: FloatArray, normals: FloatArray) -> FloatArray:
    """d r / d (t, per plane: tangent a, tangent b, d) at (t, normals): (N, 3 + 3K).

    A normal moves as n + a e1 + b e2 (normalised), so d r_i / d(a, b) = (e1, e2) . tip_i.
    """
    k = normals.shape[0]
    n_touch = touches.R.shape[0]
    tips = touches.f + touches.R @ t
    jac = np.zeros((n_touch, 3 + 3 * k))
    jac[:, :3] = np.einsum("nji,nj->ni", touches.R, normals[touches.plane])
    for j in range(k):
        rows = touches.plane == j
        e1, e2 = tangents(normals[j])
        jac[rows, 3 + 3 * j] = tips[rows] @ e1
        jac[rows, 4 + 3 * j] = tips[rows] @ e2
        jac[rows, 5 + 3 * j] = -1.0
    return jac
