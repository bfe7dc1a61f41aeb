"""Parameters of the ``kalman`` segment tracker (:mod:`trackfw_plugins.trackers.kalman`).

See docs/algorithms/segment-tracker.md#parameters. The settings of its parts live beside those
parts: the lifecycle's in :mod:`trackfw_plugins.trackers.lifecycle`, the look's in
:mod:`trackfw_plugins.trackers.appearance_memory`, the bystander tracks' in
:mod:`trackfw_plugins.trackers.bystanders`, the walk check's in
:mod:`trackfw_plugins.trackers.walk_check`, the start split's in
:mod:`trackfw_plugins.trackers.start_split`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from trackfw.stages import StageParams
from trackfw_plugins.maths.kalman import PAPER_P0, PAPER_Q, PAPER_R
from trackfw_plugins.maths.scene_registration import RegistrationSettings
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings, one_image_settings
from trackfw_plugins.trackers.appearance_memory import AppearanceSettings
from trackfw_plugins.trackers.bystanders import BystanderSettings
from trackfw_plugins.trackers.camera_motion import consecutive_frames_registration
from trackfw_plugins.trackers.lifecycle import LifecycleSettings
from trackfw_plugins.trackers.start_split import StartSplitSettings
from trackfw_plugins.trackers.walk_check import WalkCheckSettings


class KalmanTrackerParams(StageParams):
    """Parameters of the Kalman tracker; P0, Q and R default to the paper's values."""

    association: Literal["hungarian", "nearest", "tps-rpm"] = Field(
        "hungarian",
        description="'hungarian' (Kalman1), greedy 'nearest' neighbour (Kalman2) or 'tps-rpm' (Kalman3)",
    )
    rpm: TpsRpmSettings = Field(
        default_factory=one_image_settings,
        description="TPS-RPM settings for association 'tps-rpm' (one similarity from the predictions)",
    )
    gate_px_at_1080: float | None = Field(
        50.0,
        gt=0.0,
        description="association gate in pixels at 1080p, scaled by height/1080; null = no gate",
    )
    start_gate_px_at_1080: float | None = Field(
        None,
        gt=0.0,
        description="association gate of a target not yet seen by the detector since its given"
        " start position, for a detection at most a third as far as the next one, pixels at"
        " 1080p; null = gate_px_at_1080",
    )
    start_shared_hold: bool = Field(
        False,
        description="targets not yet seen since their given start positions that share their"
        " nearest detection, with fewer detections than targets among them, take nothing and"
        " hold their given positions (as if hidden) until each has a detection of its own: one"
        " box for two people who stand close together moves with one of them, and the target"
        " that took it would follow the other person",
    )
    start_split: StartSplitSettings | None = Field(
        None,
        description="over the first half second, a target whose box split trades places with"
        " the new head whose path leads back to its given point (it was given on a box it"
        " shared with a passer-by); needs bystanders; null = off"
        " (docs/algorithms/segment-tracker.md#a-start-on-a-shared-box)",
    )
    unmatched_cost_gates: float | None = Field(
        None,
        gt=0.0,
        description="Hungarian association: a target may stay unmatched at this many gates of"
        " cost, so that the solver takes a chain of matches onto neighbours' detections only"
        " when it costs less; null = as many targets matched as the gate allows (then one"
        " missed head in a tight group can shift every target onto a neighbour's detection)",
    )
    coasting_group_cost: Literal["none", "mean", "max"] = Field(
        "none",
        description="Hungarian association of a target that missed its detection on the previous"
        " frame: the 'mean' or the 'max' of its distance to its prediction and to where its"
        " offsets to the targets seen on the previous frame place it (at least two of them);"
        " 'none' = the prediction alone",
    )
    P0: float = Field(PAPER_P0, gt=0.0, description="initial state variance (P0 = P0 * I4)")
    Q: float = Field(PAPER_Q, gt=0.0, description="transition noise variance (Q = Q * I4)")
    R: float = Field(PAPER_R, gt=0.0, description="observation noise variance (R = R * I2)")
    reinit_at_b: bool = Field(
        True,
        description="after an interval, restart each filter at its frame-b position with zero velocity and P0",
    )
    lifecycle: LifecycleSettings = Field(
        default_factory=LifecycleSettings,
        description="when a target is lost, confirmed after an interval, or re-acquired",
    )
    appearance: AppearanceSettings = Field(
        default_factory=AppearanceSettings,
        description="the appearance check of re-acquisition (reads pixels unless 'none')",
    )
    bystanders: BystanderSettings | None = Field(
        None,
        description="also follow the heads no target holds, as anonymous tracks that compete"
        " with the targets in the association (Hungarian only), so that a target whose head"
        " was missed does not take a passing bystander's; null = off",
    )
    walk_check: WalkCheckSettings | None = Field(
        None,
        description="each match at b checked by the walk after it: a target whose person walks"
        " back from the target's walk before a is lost and its reports since b withdrawn;"
        " None = off (docs/algorithms/segment-tracker.md#the-walk-after-b)",
    )
    cmc: bool = Field(
        False,
        description="camera-motion compensation: warp the filters by the scene registration of"
        " the previous frame to this one before predicting (reads pixels)",
    )
    cmc_registration: RegistrationSettings = Field(
        default_factory=consecutive_frames_registration,
        description="the registration of consecutive frames for cmc",
    )

    @model_validator(mode="after")
    def _split_needs_bystanders(self) -> KalmanTrackerParams:
        if self.start_split is not None and self.bystanders is None:
            raise ValueError(
                "start_split needs bystanders (the new head is a bystander track); expected"
                " bystanders set, e.g. bystanders: {}"
            )
        return self


__all__ = ["KalmanTrackerParams"]
