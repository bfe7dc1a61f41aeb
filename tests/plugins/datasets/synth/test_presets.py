"""The paper preset's statistics and the interval layout, computed on the plan (no pixels)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.datasets.synth.presets import (
    MIN_LEAD_FRAMES,
    MIN_TAIL_FRAMES,
    SITES,
    custom_plan,
    demo_plan,
    layout_intervals,
    paper_interval_lengths,
    paper_plan,
)


@pytest.mark.parametrize("seed", [0, 1, 12345])
def test_paper_plan_matches_the_papers_dataset(seed: int) -> None:
    plans = paper_plan(seed)
    assert len(plans) == 30
    assert len({plan.name for plan in plans}) == 30
    with_interval = [plan for plan in plans if plan.intervals]
    assert len(with_interval) == 26
    assert all(len(plan.intervals) == 1 for plan in with_interval)
    kinds = Counter(plan.intervals[0].kind for plan in with_interval)
    assert kinds == {"sky": 11, "group": 10, "path": 5}
    lengths = [plan.n_frames for plan in plans]
    assert min(lengths) == 90 and max(lengths) == 351
    interval_lengths = [plan.intervals[0].length for plan in with_interval]
    assert min(interval_lengths) == 18 and max(interval_lengths) == 249
    assert abs(float(np.mean(interval_lengths)) - 83.0) < 2.0
    sites = Counter(plan.site.name for plan in plans)
    assert len(sites) == 10 and set(sites.values()) == {3}
    assert all(5 <= plan.n_targets <= 10 for plan in plans)
    for plan in with_interval:
        interval = plan.intervals[0]
        assert interval.start >= MIN_LEAD_FRAMES
        assert interval.end <= plan.n_frames - 1 - MIN_TAIL_FRAMES


def test_paper_plan_is_deterministic_and_seed_dependent() -> None:
    assert paper_plan(3) == paper_plan(3)
    assert paper_plan(3) != paper_plan(4)


def test_paper_plan_options_change_counts_and_lengths() -> None:
    plans = paper_plan(0, videos=35, frames=400, intervals=2)
    assert len(plans) == 35
    assert all(plan.n_frames == 400 for plan in plans)
    with_interval = [plan for plan in plans if plan.intervals]
    assert all(len(plan.intervals) == 2 for plan in with_interval)
    for plan in with_interval:
        first, second = plan.intervals
        assert second.start - first.end - 1 >= 20  # a segment of normal frames between them


def test_interval_lengths_keep_extremes_and_mean() -> None:
    lengths = paper_interval_lengths(np.random.default_rng(5), 40)
    assert min(lengths) == 18 and max(lengths) == 249
    assert abs(np.mean(lengths) - 83.0) < 2.0


def test_layout_refuses_a_video_too_short() -> None:
    with pytest.raises(UserError, match="too short"):
        layout_intervals(np.random.default_rng(0), 60, [40], ["sky"])


def test_custom_plan_cycles_kinds_and_sites() -> None:
    plans = custom_plan(7, videos=4, frames=200, intervals=1)
    assert [plan.intervals[0].kind for plan in plans] == ["sky", "group", "path", "sky"]
    assert [plan.site for plan in plans] == list(SITES[:4])
    assert all(plan.n_frames == 200 for plan in plans)


def test_demo_plan_is_the_documented_clip() -> None:
    plan = demo_plan()
    assert (plan.width, plan.height, plan.n_frames, plan.n_targets) == (640, 360, 150, 6)
    assert [(i.start, i.length, i.kind) for i in plan.intervals] == [(60, 30, "sky")]
