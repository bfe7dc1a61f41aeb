"""Thin-plate spline helpers in 2-D: kernel, QR basis, regularised fit and evaluation.

The conventions follow Chui & Rangarajan's RPM demo (``ctps_gen.m``): the kernel is
``Φ(r) = ½ r² log r² = r² log r`` with ``Φ(0) = 0``; a spline maps a point ``u`` to
``[1, u] d + Φ(u, U) c`` with ``d`` (3, 3) the affine part and ``c`` (K, 3) the warping
coefficients whose first column is zero. See docs/algorithms/tps-rpm.md#algorithm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackfw.arrays import FloatArray

_KERNEL_EPSILON = 1e-10


def tps_kernel(points_a: FloatArray, points_b: FloatArray) -> FloatArray:
    """The 2-D thin-plate kernel matrix between two point sets.

    Args:
        points_a: (P, 2) points.
        points_b: (K, 2) points.

    Returns:
        (P, K) matrix with entries ``½ r² log r²``; entries with ``r² < 1e-10`` are 0.

    >>> tps_kernel(np.array([[0.0, 0.0]]), np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])).round(4)
    array([[0.    , 0.    , 2.7726]])
    """
    difference = points_a[:, None, :] - points_b[None, :, :]
    squared = np.einsum("pkd,pkd->pk", difference, difference)
    # The mask keeps log away from 0; those entries are the r -> 0 limit, which is 0.
    safe = np.where(squared < _KERNEL_EPSILON, 1.0, squared)
    return np.where(squared < _KERNEL_EPSILON, 0.0, 0.5 * squared * np.log(safe))


def homogeneous(points: FloatArray) -> FloatArray:
    """Prepend a column of ones: (P, 2) -> (P, 3)."""
    return np.hstack([np.ones((points.shape[0], 1)), points])


@dataclass(frozen=True)
class TpsBasis:
    """Per-template quantities of a regularised TPS fit (they depend on the template only).

    Attributes:
        template: (K, 2) control points.
        kernel: (K, K) Φ between the control points.
        q1: (K, 3) first block of the full QR factor of ``[1, template]``.
        q2: (K, K-3) null-space block (empty when K <= 3).
        r: (3, 3) triangular factor (its rows are zero-padded when K < 3).
    """

    template: FloatArray
    kernel: FloatArray
    q1: FloatArray
    q2: FloatArray
    r: FloatArray

    @classmethod
    def from_template(cls, template: FloatArray) -> TpsBasis:
        """Build Φ and the full QR factorisation of the homogeneous template (K, 2)."""
        template = np.asarray(template, dtype=np.float64)
        count = template.shape[0]
        q_full, r_full = np.linalg.qr(homogeneous(template), mode="complete")
        r = np.zeros((3, 3))
        rows = min(3, count)
        r[:rows] = r_full[:rows]
        q1 = np.zeros((count, 3))
        q1[:, :rows] = q_full[:, :rows]
        q2 = q_full[:, 3:] if count > 3 else np.zeros((count, 0))
        return cls(template, tps_kernel(template, template), q1, q2, r)

    def linear_operators(
        self, lambda_bending: FloatArray, lambda_affine: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Operators of the regularised fit for several (λ1, λ2) pairs at once.

        The fit of ``ctps_gen_cd_regularized`` is linear in the targets Y = [1, y]:
        ``c = C Y`` and ``d = G0 + D Y``. We return them so that one fit is two small
        matrix products.

        Args:
            lambda_bending: (L,) λ1 values (> 0).
            lambda_affine: (L,) λ2 values (> 0).

        Returns:
            ``C`` (L, K, K), ``D`` (L, 3, K) and ``G0`` (L, 3, 3).
        """
        lambda_bending = np.atleast_1d(np.asarray(lambda_bending, dtype=np.float64))
        lambda_affine = np.atleast_1d(np.asarray(lambda_affine, dtype=np.float64))
        levels = lambda_bending.shape[0]
        count = self.template.shape[0]
        # C = Q2 (Q2ᵀΦQ2 + λ1 I)⁻¹ Q2ᵀ through one symmetric eigendecomposition for all λ1.
        if self.q2.shape[1] > 0:
            reduced = self.q2.T @ self.kernel @ self.q2
            eigenvalues, eigenvectors = np.linalg.eigh(0.5 * (reduced + reduced.T))
            basis = self.q2 @ eigenvectors
            inverse_diagonal = 1.0 / (eigenvalues[None, :] + lambda_bending[:, None])
            bending_operator = np.einsum("ki,li,ji->lkj", basis, inverse_diagonal, basis)
        else:
            bending_operator = np.zeros((levels, count, count))
        gram = self.r.T @ self.r
        identity = np.eye(3)
        affine_inverse = np.linalg.inv(gram[None] + lambda_affine[:, None, None] * identity)
        # d = I + (RᵀR + λ2 I)⁻¹ (Rᵀ Q1ᵀ (Y − Φ c) − RᵀR)
        projector = self.r.T @ self.q1.T  # (3, K)
        residual = np.eye(count)[None] - self.kernel[None] @ bending_operator  # (L, K, K)
        affine_operator = affine_inverse @ projector[None] @ residual
        affine_offset = identity[None] - affine_inverse @ gram[None]
        return bending_operator, affine_operator, affine_offset

    def fit(
        self, targets: FloatArray, lambda_bending: float, lambda_affine: float
    ) -> tuple[FloatArray, FloatArray]:
        """Regularised TPS from the template to ``targets`` (K, 2).

        Returns:
            ``c`` (K, 3) with a zero first column and ``d`` (3, 3).
        """
        bending, affine, offset = self.linear_operators(
            np.array([lambda_bending]), np.array([lambda_affine])
        )
        targets_h = homogeneous(np.asarray(targets, dtype=np.float64))
        return bending[0] @ targets_h, offset[0] + affine[0] @ targets_h

    def evaluate(self, points: FloatArray, c: FloatArray, d: FloatArray) -> FloatArray:
        """Map points (P, 2) through the spline ``(c, d)``; returns (P, 2)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        mapped = homogeneous(points) @ d + tps_kernel(points, self.template) @ c
        return mapped[:, 1:3]

    def bending_energy(self, c: FloatArray) -> float:
        """Discrete bending energy ``trace(c[:,1:]ᵀ Φ c[:,1:])`` (≥ 0, no 8π factor)."""
        warp = c[:, 1:3]
        return float(max(np.einsum("ki,kj,ji->", warp, self.kernel, warp), 0.0))
