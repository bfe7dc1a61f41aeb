"""Targets that walk out of view and come back (``--leave``, ``--preset paper-leave``)."""

from __future__ import annotations

import hashlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.formats.annotations import write_annotations
from trackfw_plugins.datasets.synth.cli import build_plans, run_synth
from trackfw_plugins.datasets.synth.presets import (
    LEAVE_MIN_FRAMES,
    VideoPlan,
    custom_plan,
    paper_plan,
)
from trackfw_plugins.datasets.synth.simulate import Simulation, simulate


def _leave_plans(seed: int, count: int = 3) -> list[VideoPlan]:
    plans = build_plans("paper-leave", seed, count, None, None, (640, 360), 30.0, None, None)
    assert all(plan.leave == 1 and plan.n_frames >= LEAVE_MIN_FRAMES for plan in plans)
    assert all(plan.preset == "paper-leave" for plan in plans)
    return plans


def _excursions(simulation: Simulation) -> list[dict]:
    notes = simulation.crowd.notes.get("excursions")
    assert isinstance(notes, list)
    return notes


@pytest.mark.parametrize("seed", [5, 8])
def test_a_leaving_target_is_absent_from_the_ground_truth_while_away(seed: int) -> None:
    left = 0
    for plan in _leave_plans(seed):
        simulation = simulate(plan)
        infoless = simulation.infoless()
        for excursion in _excursions(simulation):
            left += 1
            target = excursion["id"]
            leaves, (away_first, away_last), back = (
                excursion["leaves"],
                excursion["away"],
                excursion["back"],
            )
            assert 1 <= target <= plan.n_targets
            assert leaves < away_first <= away_last < back <= plan.n_frames
            # 1-based away frames, all informative: the target is seen missing.
            away = range(away_first - 1, away_last)
            assert not infoless[list(away)].any()
            assert all(target not in simulation.targets.get(frame, {}) for frame in away)
            heads = {(frame, person) for frame, person, *_ in simulation.heads}
            assert all((frame, target) not in heads for frame in away)
            # In view before it leaves and again once it is back with its group.
            before = [f for f in range(leaves - 1) if target in simulation.targets.get(f, {})]
            after = [
                f for f in range(back, plan.n_frames) if target in simulation.targets.get(f, {})
            ]
            assert before and after
            # The others stay: only the leaver goes missing on the away frames.
            present = [len(simulation.targets.get(frame, {})) for frame in away]
            assert max(present) >= plan.n_targets - 2
    assert left >= 2, "too few of the videos had a walk out of view"


def test_excursions_are_deterministic_and_depend_on_the_seed() -> None:
    plan = _leave_plans(5, 1)[0]
    first, second = simulate(plan), simulate(plan)
    assert _excursions(first) == _excursions(second)
    assert first.targets == second.targets and first.heads == second.heads
    assert np.array_equal(first.crowd.positions, second.crowd.positions)
    other = simulate(replace(plan, seed=plan.seed + 1))
    assert _excursions(other) != _excursions(first)


def test_leaving_changes_only_the_leavers_path() -> None:
    plan = _leave_plans(5, 1)[0]
    leaving, staying = simulate(plan), simulate(replace(plan, leave=0))
    assert "excursions" not in staying.crowd.notes
    leavers = [excursion["id"] - 1 for excursion in _excursions(leaving)]
    assert leavers
    others = np.setdiff1d(np.arange(leaving.crowd.count), leavers)
    assert np.array_equal(leaving.crowd.positions[others], staying.crowd.positions[others])
    assert not np.array_equal(leaving.crowd.positions[leavers], staying.crowd.positions[leavers])
    # The wearer watches the group as planned without the leaver, and the lighting is unchanged.
    assert np.array_equal(leaving.motion.poses, staying.motion.poses)
    assert np.array_equal(leaving.gain, staying.gain)


def _digest(simulation: Simulation, folder: Path) -> str:
    write_annotations(folder, simulation.targets, simulation.heads, simulation.intervals)
    digest = hashlib.sha256()
    for name in ("gt.csv", "heads.csv", "intervals.csv"):
        digest.update((folder / name).read_bytes())
    digest.update(np.round(simulation.motion.poses, 6).tobytes())
    return digest.hexdigest()[:16]


def test_existing_presets_are_drawn_as_before_the_option(tmp_path: Path) -> None:
    """Golden digests of the annotations written before ``--leave`` existed: a dataset generated
    without the option must not change (a deliberate generator change updates them)."""
    paper = replace(paper_plan(0, videos=1)[0], width=320, height=180)
    custom = custom_plan(3, videos=1, frames=80, width=320, height=180)[0]
    paper_digest = _digest(simulate(paper), tmp_path / "paper")
    custom_digest = _digest(simulate(custom), tmp_path / "custom")
    assert (paper_digest, custom_digest) == (PAPER_DIGEST, CUSTOM_DIGEST)


def test_bad_leave_counts_are_refused(tmp_path: Path) -> None:
    for leave in (-1, 6):
        with pytest.raises(UserError, match="--leave"):
            run_synth(tmp_path / "x", preset="paper-leave", leave=leave, echo=False)
    assert not (tmp_path / "x").exists()


def test_leave_applies_to_any_plan_and_frames_are_kept_when_given() -> None:
    plans = build_plans(None, 1, 2, 200, 1, (320, 180), 30.0, None, None, leave=2)
    assert [plan.leave for plan in plans] == [2, 2] and {p.n_frames for p in plans} == {200}
    plans = build_plans("paper-leave", 1, 2, 500, None, (320, 180), 30.0, None, None, leave=0)
    assert [plan.leave for plan in plans] == [0, 0] and {p.n_frames for p in plans} == {500}


PAPER_DIGEST = "dde78a5bc668cddc"
CUSTOM_DIGEST = "b22ab2516f2ec093"


def test_targets_k_makes_k_people_of_interest_among_bystanders(tmp_path: Path) -> None:
    plan = build_plans(None, 2, 1, 120, 1, (640, 360), 30.0, None, None, targets=2)[0]
    assert plan.n_targets == 2
    simulation = simulate(plan)
    gt_ids = {i for targets in simulation.targets.values() for i in targets}
    head_ids = {person for _, person, *_ in simulation.heads}
    assert gt_ids == {1, 2} and len(head_ids - gt_ids) > 2 * len(gt_ids)
    for targets in (0, 13):
        with pytest.raises(UserError, match="--targets"):
            run_synth(tmp_path / "x", targets=targets, echo=False)
    with pytest.raises(UserError, match="at most --targets"):
        run_synth(tmp_path / "x", targets=2, leave=3, echo=False)
    assert not (tmp_path / "x").exists()
