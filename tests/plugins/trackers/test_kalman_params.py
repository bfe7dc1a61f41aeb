"""The ``kalman`` tracker's parameters (``trackfw_plugins.trackers.kalman_params``)."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from trackfw_plugins.maths.kalman import PAPER_P0, PAPER_Q, PAPER_R
from trackfw_plugins.maths.tps_rpm_template import one_image_settings
from trackfw_plugins.trackers.kalman import KalmanTracker
from trackfw_plugins.trackers.kalman_params import KalmanTrackerParams


def test_defaults_are_the_papers_filter_and_one_image_tps_rpm() -> None:
    params = KalmanTrackerParams()
    assert (params.P0, params.Q, params.R) == (PAPER_P0, PAPER_Q, PAPER_R)
    assert params.association == "hungarian"
    assert params.rpm == one_image_settings()
    assert (params.rpm.normalisation, params.rpm.precision) == ("template", "float32")


def test_the_tracker_reads_these_parameters_and_refuses_bad_ones() -> None:
    tracker = KalmanTracker(KalmanTrackerParams(gate_px_at_1080=70.0))
    assert tracker.params.gate_px_at_1080 == 70.0
    with pytest.raises(ValidationError):
        KalmanTrackerParams(gate_px_at_1080=-1.0)
