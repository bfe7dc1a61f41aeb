"""Constant-velocity Kalman filter for point targets.

See docs/algorithms/segment-tracker.md#kalman-model.

The state of one target is ``s = (x, y, vx, vy)``; the observation is the head centre ``(x, y)``.
The filter is batched over targets: means are ``(K, 4)`` and covariances ``(K, 4, 4)``.
P0, Q and R are the paper's; the correction uses the Joseph form for numerical safety.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackfw.arrays import FloatArray

#: Paper values (Yu et al. 2018, section 4.2): diagonal P0, Q and R.
PAPER_P0 = 1.0e3
PAPER_Q = 1.0e-3
PAPER_R = 1.0e-3


def transition_matrix() -> FloatArray:
    """``(4, 4)`` constant-velocity transition F for one frame.

    >>> transition_matrix() @ np.array([1.0, 2.0, 0.5, -1.0])
    array([ 1.5,  1. ,  0.5, -1. ])
    """
    return np.array(
        [[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    )


def observation_matrix() -> FloatArray:
    """``(2, 4)`` observation H that reads the position from the state."""
    return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def extrapolate(means: FloatArray, horizon: int) -> FloatArray:
    """``(K, 2)`` positions of ``(K, 4)`` states after ``horizon`` frames without correction.

    u = H·F^h·s, which is position + h·velocity (the paper's "TR" prediction across a gap).

    >>> extrapolate(np.array([[10.0, 20.0, 1.5, -2.0]]), 4)
    array([[16., 12.]])
    """
    if horizon < 0:
        raise ValueError(f"horizon must be non-negative, got {horizon}")
    propagate = observation_matrix() @ np.linalg.matrix_power(transition_matrix(), horizon)
    return np.asarray(means, dtype=np.float64).reshape(-1, 4) @ propagate.T


@dataclass
class KalmanBank:
    """Independent constant-velocity Kalman filters, one per target.

    Attributes:
        means: ``(K, 4)`` state means.
        covariances: ``(K, 4, 4)`` state covariances.
        process_noise: Q, scalar times identity.
        observation_noise: R, scalar times identity.
        initial_variance: P0, scalar times identity.
    """

    means: FloatArray
    covariances: FloatArray
    process_noise: float = PAPER_Q
    observation_noise: float = PAPER_R
    initial_variance: float = PAPER_P0

    @classmethod
    def start(
        cls,
        positions: FloatArray,
        initial_variance: float = PAPER_P0,
        process_noise: float = PAPER_Q,
        observation_noise: float = PAPER_R,
    ) -> KalmanBank:
        """Filters at ``(K, 2)`` positions with zero velocity and covariance P0.

        >>> bank = KalmanBank.start(np.array([[10.0, 20.0]]))
        >>> bank.positions.tolist()
        [[10.0, 20.0]]
        """
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        count = len(positions)
        means = np.zeros((count, 4))
        means[:, :2] = positions
        covariances = np.tile(np.eye(4) * initial_variance, (count, 1, 1))
        return cls(means, covariances, process_noise, observation_noise, initial_variance)

    @property
    def positions(self) -> FloatArray:
        """``(K, 2)`` current positions."""
        return self.means[:, :2].copy()

    @property
    def velocities(self) -> FloatArray:
        """``(K, 2)`` current velocities in pixels per frame."""
        return self.means[:, 2:].copy()

    def keep(self, rows: NDArray[np.int64] | NDArray[np.bool_]) -> None:
        """Keep only the filters ``rows`` (indices, in that order, or a ``(K,)`` mask)."""
        self.means, self.covariances = self.means[rows], self.covariances[rows]

    def add(self, positions: FloatArray) -> None:
        """Append filters at ``(M, 2)`` positions with zero velocity and covariance P0.

        >>> bank = KalmanBank.start(np.array([[10.0, 20.0]]))
        >>> bank.add(np.array([[30.0, 40.0]]))
        >>> bank.positions.tolist()
        [[10.0, 20.0], [30.0, 40.0]]
        """
        born = KalmanBank.start(positions, self.initial_variance)
        self.means = np.concatenate([self.means, born.means])
        self.covariances = np.concatenate([self.covariances, born.covariances])

    def predict(self, steps: int = 1) -> None:
        """Advance every filter by ``steps`` frames without correction (``P += Q`` each step)."""
        transition = transition_matrix()
        process = np.eye(4) * self.process_noise
        for _ in range(steps):
            self.means = self.means @ transition.T
            self.covariances = transition @ self.covariances @ transition.T + process

    def predicted(self, steps: int = 1) -> tuple[FloatArray, FloatArray]:
        """Means ``(K, 4)`` and covariances ``(K, 4, 4)`` after ``steps`` frames, state unchanged."""
        clone = KalmanBank(
            self.means.copy(), self.covariances.copy(), self.process_noise, self.observation_noise
        )
        clone.predict(steps)
        return clone.means, clone.covariances

    def warp(self, matrix: FloatArray) -> None:
        """Carry every filter through a ``(3, 3)`` affine image map (camera-motion compensation).

        The position maps as a point (x' = A x + t), the velocity as a direction (v' = A v) and
        the covariance with the linear part (P' = T P Tᵀ, T = diag(A, A)).
        """
        matrix = np.asarray(matrix, dtype=np.float64)
        linear, shift = matrix[:2, :2], matrix[:2, 2]
        self.means[:, :2] = self.means[:, :2] @ linear.T + shift
        self.means[:, 2:] = self.means[:, 2:] @ linear.T
        both = np.zeros((4, 4))
        both[:2, :2] = both[2:, 2:] = linear
        self.covariances = both @ self.covariances @ both.T

    def correct(self, target_indices: NDArray[np.int64], observations: FloatArray) -> None:
        """Correct the filters ``target_indices`` with ``(M, 2)`` observed positions.

        Targets not listed keep their prediction.
        """
        if len(target_indices) == 0:
            return
        observe = observation_matrix()
        noise = np.eye(2) * self.observation_noise
        prior_means = self.means[target_indices]
        prior_covariances = self.covariances[target_indices]
        innovation_covariance = observe @ prior_covariances @ observe.T + noise
        gain = prior_covariances @ observe.T @ np.linalg.inv(innovation_covariance)
        residual = np.asarray(observations, dtype=np.float64) - prior_means[:, :2]
        self.means[target_indices] = prior_means + np.einsum("kij,kj->ki", gain, residual)
        identity_minus = np.eye(4) - gain @ observe
        self.covariances[target_indices] = (
            identity_minus @ prior_covariances @ identity_minus.transpose(0, 2, 1)
            + gain @ noise @ gain.transpose(0, 2, 1)
        )
