"""CEM's settings: the energy's term weights, the descent and the jump moves' gates, in one place.

The energy (:mod:`~trackfw_plugins.batch_trackers.cem_energy`), the jump moves
(:mod:`~trackfw_plugins.batch_trackers.cem_moves`) and the tracker
(:mod:`~trackfw_plugins.batch_trackers.cem`) all read these same validated settings, so each
default is written once. See ``docs/algorithms/batch-trackers.md#cem``.
"""

from __future__ import annotations

from pydantic import Field

from trackfw.stages import StageParams


class CemParams(StageParams):
    """CEM settings; defaults are the reference's 2-D defaults (``default2d.ini``)."""

    target_size: float | None = Field(
        None, gt=0.0, description="c in px, the length scale of every term; null = image width / 30"
    )
    existence: float = Field(0.1, ge=0.0, description="lambda: cost of each target-frame in E_det")
    detection_weight: float = Field(1.0, ge=0.0, description="weight of E_det")
    dynamics_weight: float = Field(2.0, ge=0.0, description="weight of E_dyn")
    exclusion_weight: float = Field(1.0, ge=0.0, description="weight of E_exc")
    persistence_weight: float = Field(1.0, ge=0.0, description="weight of E_per")
    regulariser_weight: float = Field(0.5, ge=0.0, description="weight of E_reg")
    cg_iterations: int = Field(30, ge=1, description="conjugate-gradient iterations per descent")
    max_epochs: int = Field(15, ge=0, description="rounds of jump moves")
    merge_max_gap: int = Field(15, ge=1, description="merge: largest gap in frames, exclusive")
    merge_max_distance: float = Field(
        5.0, gt=0.0, description="merge: largest distance between the ends, in c"
    )
    merge_max_speed: float = Field(
        3.0, gt=0.0, description="merge: largest speed across the gap, in c per frame"
    )
    max_extension: int = Field(
        50, ge=1, description="grow / shrink: most frames added or cut at an end"
    )
    add_per_call: int = Field(8, ge=0, description="add: most new targets per call")
    add_free_distance: float = Field(
        2.0, gt=0.0, description="add: a detection is free when no target is within this, in c"
    )
    split_min_length: int = Field(6, ge=6, description="split: shortest target that is split")
