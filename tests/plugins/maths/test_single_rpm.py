"""TPS-RPM of small point sets on two-dimensional arrays agrees with the batched tps_rpm."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.maths.single_rpm import covers, tps_rpm_groups, tps_rpm_single
from trackfw_plugins.maths.tps_rpm import tps_rpm
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings

# The GTCSA-like tracker's settings (13 levels of 2 updates; see its module) and the defaults.
COARSE = TpsRpmSettings(anneal_rate=0.7, T_finalfac=100.0, perT_maxit=2, sinkhorn_maxit=5)
SETTINGS = [COARSE, TpsRpmSettings()]


def _problem(random: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A template of 3-16 points and data that moves most of them, with m != n allowed."""
    count, width = random.integers(3, 17, size=2)
    template = random.uniform(0.0, 800.0, size=(count, 2))
    shared = min(count, width)
    moved = template[:shared] + random.normal(0.0, 15.0, size=(shared, 2))
    clutter = random.uniform(0.0, 800.0, size=(max(width - count, 0), 2))
    data = np.vstack([moved, clutter])
    return template, data[random.permutation(len(data))]


def _assert_same(expected, result) -> None:  # type: ignore[no-untyped-def]
    assert np.array_equal(result.matches, expected.matches)
    np.testing.assert_allclose(result.correspondence, expected.correspondence, atol=1e-9)
    probe = expected.template_centre + np.array([[3.0, -4.0], [50.0, 20.0]])
    np.testing.assert_allclose(result.transform(probe), expected.transform(probe), atol=1e-8)
    np.testing.assert_allclose(result.warped_template, expected.warped_template, atol=1e-8)
    assert result.bending_energy == pytest.approx(expected.bending_energy, rel=1e-8, abs=1e-12)


@pytest.mark.parametrize("settings", SETTINGS)
def test_one_problem_agrees_with_tps_rpm(settings: TpsRpmSettings) -> None:
    random = np.random.default_rng(3)
    for _ in range(25):
        template, data = _problem(random)
        _assert_same(tps_rpm(template, data, settings), tps_rpm_single(template, data, settings))


def test_problems_annealed_together_agree_with_each_alone() -> None:
    # Block-diagonal: each problem must see only its own points, and stop its Sinkhorn
    # iterations by its own test.
    random = np.random.default_rng(4)
    for _ in range(10):
        problems = [_problem(random) for _ in range(int(random.integers(2, 5)))]
        results = tps_rpm_groups(problems, COARSE)
        assert len(results) == len(problems)
        for (template, data), result in zip(problems, results, strict=True):
            _assert_same(tps_rpm(template, data, COARSE), result)


def test_empty_sets_and_uncovered_settings_are_tps_rpm_itself() -> None:
    random = np.random.default_rng(5)
    template, data = _problem(random)
    paper = TpsRpmSettings(schedule="paper", anneal_rate=0.8)
    assert not covers(paper) and covers(COARSE)
    problems = [(template, data), (template, np.zeros((0, 2))), (np.zeros((0, 2)), data)]
    for settings in (paper, COARSE):
        for (one, other), result in zip(problems, tps_rpm_groups(problems, settings), strict=True):
            expected = tps_rpm(one, other, settings)
            if settings is paper or len(one) == 0 or len(other) == 0:
                assert np.array_equal(result.correspondence, expected.correspondence)
                assert np.array_equal(result.matches, expected.matches)
    assert tps_rpm_groups([], COARSE) == []
