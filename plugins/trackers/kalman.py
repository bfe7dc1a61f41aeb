"""The ``kalman`` segment tracker: Kalman filter + association.

See docs/algorithms/segment-tracker.md#segment-tracker.

Kalman1 of the paper is ``association: hungarian``, Kalman2 ``association: nearest`` and Kalman3
``association: tps-rpm`` (TPS-RPM between all predictions and detections on every frame).
The filter maths lives in :mod:`trackfw_plugins.maths.kalman`, the association in
:mod:`trackfw_plugins.maths.assignment`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray, IntArray
from trackfw.records import NO_MATCH, Detections, TargetState, VideoContext
from trackfw.stages import StageParams, Tracker
from trackfw_plugins.maths.assignment import distance_matrix, greedy_nearest, hungarian
from trackfw_plugins.maths.kalman import PAPER_P0, PAPER_Q, PAPER_R, KalmanBank
from trackfw_plugins.maths.tps_rpm import match_points
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings


def _kalman3_rpm() -> TpsRpmSettings:
    return TpsRpmSettings(normalisation="template", precision="float32")


class KalmanTrackerParams(StageParams):
    """Parameters of the Kalman tracker; P0, Q and R default to the paper's values."""

    association: Literal["hungarian", "nearest", "tps-rpm"] = Field(
        "hungarian",
        description="'hungarian' (Kalman1), greedy 'nearest' neighbour (Kalman2) or 'tps-rpm' (Kalman3)",
    )
    rpm: TpsRpmSettings = Field(
        default_factory=_kalman3_rpm,
        description="TPS-RPM settings for association 'tps-rpm' (one similarity from the predictions)",
    )
    gate_px_at_1080: float | None = Field(
        50.0,
        gt=0.0,
        description="association gate in pixels at 1080p, scaled by height/1080; null = no gate",
    )
    P0: float = Field(PAPER_P0, gt=0.0, description="initial state variance (P0 = P0 * I4)")
    Q: float = Field(PAPER_Q, gt=0.0, description="transition noise variance (Q = Q * I4)")
    R: float = Field(PAPER_R, gt=0.0, description="observation noise variance (R = R * I2)")
    reinit_at_b: bool = Field(
        True,
        description="after an interval, restart each filter at its frame-b position with zero velocity and P0",
    )


class KalmanTracker(Tracker[KalmanTrackerParams]):
    """Constant-velocity Kalman filters with Hungarian or nearest-neighbour association."""

    name = "kalman"

    def start(self, video: VideoContext) -> None:
        params = self.params
        self.gate = (
            None
            if params.gate_px_at_1080 is None
            else params.gate_px_at_1080 * video.height / 1080.0
        )
        self.bank = KalmanBank.start(np.zeros((0, 2)), params.P0, params.Q, params.R)
        self.target_ids = np.zeros(0, dtype=np.int64)
        self.matched = np.zeros(0, dtype=np.int64)

    def initialise(self, t: int, target_ids: IntArray, positions: FloatArray) -> None:
        params = self.params
        self.target_ids = np.asarray(target_ids, dtype=np.int64)
        self.bank = KalmanBank.start(positions, params.P0, params.Q, params.R)
        self.matched = np.full(len(self.target_ids), NO_MATCH, dtype=np.int64)

    def associate(self, predicted: FloatArray, detections: Detections) -> IntArray:
        """Row of ``detections`` for each predicted target, ``-1`` when none (gated)."""
        if self.params.association == "tps-rpm":
            rows, _, _ = match_points(predicted, detections.points, self.params.rpm)
            return rows
        cost = distance_matrix(predicted, detections.points)
        if self.params.association == "nearest":
            return greedy_nearest(cost, self.gate)
        return hungarian(cost, self.gate)

    def step(self, t: int, detections: Detections) -> None:
        self.bank.predict()
        rows = self.associate(self.bank.positions, detections) if len(detections) else None
        self.matched = np.full(len(self.target_ids), NO_MATCH, dtype=np.int64)
        if rows is None:
            return
        targets = np.flatnonzero(rows >= 0)
        self.bank.correct(targets, detections.points[rows[targets]])
        self.matched[targets] = detections.index[rows[targets]]

    def reinitialise(self, t: int, positions: FloatArray, matched_detection: IntArray) -> None:
        params = self.params
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        if params.reinit_at_b:
            # The old velocity belongs to the pre-interval camera pose
            # (docs/algorithms/segment-tracker.md#re-initialisation-at-b).
            self.bank = KalmanBank.start(positions, params.P0, params.Q, params.R)
        else:
            self.bank.predict()
            self.bank.means[:, :2] = positions
        self.matched = np.asarray(matched_detection, dtype=np.int64).copy()

    def positions(self) -> FloatArray:
        return self.bank.means[:, :2].copy()

    def states(self) -> list[TargetState]:
        means, covariances = self.bank.means, self.bank.covariances
        return [
            TargetState(
                target_id=int(target_id),
                position=means[row, :2].copy(),
                velocity=means[row, 2:].copy(),
                covariance=covariances[row],
                matched_detection=int(self.matched[row]),
            )
            for row, target_id in enumerate(self.target_ids)
        ]
