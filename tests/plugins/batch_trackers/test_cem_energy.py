"""CEM energy: every term's analytic gradient against central finite differences."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from trackfw_plugins.batch_trackers.cem_energy import (
    Scene,
    cross_exclusion_energy,
    detection_energy,
    dynamics_energy,
    exclusion_energy,
    persistence_energy,
    regulariser_energy,
    total_energy,
)
from trackfw_plugins.batch_trackers.cem_params import CemParams

FRAMES, TARGETS = 12, 4


def _state(seed: int = 0) -> tuple[np.ndarray, np.ndarray, Scene]:
    random = np.random.default_rng(seed)
    positions = random.uniform(40, 600, (FRAMES, TARGETS, 2))
    alive = np.zeros((FRAMES, TARGETS), dtype=bool)
    for target, (start, end) in enumerate([(0, 11), (2, 9), (4, 11), (1, 6)]):
        alive[start : end + 1, target] = True
    detections = random.uniform(0, 640, (FRAMES, 5, 2))
    scores = random.uniform(0.2, 1.0, (FRAMES, 5))
    scores[:, 4] = 0.0  # padding
    return positions, alive, Scene(detections, scores, 640.0, 480.0, 21.0)


def _numeric(
    energy: Callable[[np.ndarray], float], positions: np.ndarray, alive: np.ndarray
) -> np.ndarray:
    gradient = np.zeros_like(positions)
    step = 1e-4
    for index in zip(*np.nonzero(alive), strict=True):
        for axis in range(2):
            shifted = positions.copy()
            shifted[(*index, axis)] += step
            upper = energy(shifted)
            shifted[(*index, axis)] -= 2 * step
            gradient[(*index, axis)] = (upper - energy(shifted)) / (2 * step)
    return gradient


TERMS: dict[str, Callable[[np.ndarray, np.ndarray, Scene], tuple[float, np.ndarray]]] = {
    "detection": lambda p, a, s: detection_energy(p, a, s, 0.1),
    "dynamics": lambda p, a, s: dynamics_energy(p, a, s.target_size),
    "exclusion": lambda p, a, s: exclusion_energy(p, a, s.target_size),
    "persistence": lambda p, a, s: persistence_energy(p, a, s),
    "total": lambda p, a, s: total_energy(p, a, s, CemParams()),
    # Targets 0 and 1 move, 2 and 3 are held still (the descent after a jump move).
    "cross-exclusion": lambda p, a, s: _cross(p, a, s),
}


def _cross(positions: np.ndarray, alive: np.ndarray, scene: Scene) -> tuple[float, np.ndarray]:
    fixed = (positions[:, 2:].copy(), alive[:, 2:])
    energy, gradient = cross_exclusion_energy(positions[:, :2], alive[:, :2], fixed, 21.0)
    return energy, np.concatenate([gradient, np.zeros_like(positions[:, 2:])], axis=1)


@pytest.mark.parametrize("term", sorted(TERMS))
def test_every_gradient_matches_finite_differences(term: str) -> None:
    positions, alive, scene = _state()
    function = TERMS[term]
    _, analytic = function(positions, alive, scene)
    moving = alive.copy()
    if term == "cross-exclusion":
        moving[:, 2:] = False
        frozen = positions.copy()
        function = lambda p, a, s: _cross(np.concatenate([p[:, :2], frozen[:, 2:]], 1), a, s)  # noqa: E731
    numeric = _numeric(lambda p: function(p, alive, scene)[0], positions, moving)
    scale = max(np.abs(numeric).max(), 1e-8)
    assert np.abs(analytic - numeric).max() / scale < 1e-5
    # The gradient is zero where a target does not live (except the pure per-frame terms).
    assert np.abs(analytic[~alive]).max() == 0.0 or term in (
        "dynamics",
        "exclusion",
        "cross-exclusion",
    )
    assert np.abs(numeric).max() > 0.0


def test_constant_velocity_has_no_dynamics_energy() -> None:
    t = np.arange(FRAMES, dtype=float)[:, None, None]
    positions = np.array([[100.0, 50.0], [300.0, 200.0]])[None] + t * np.array(
        [[3.0, 1.0], [-2.0, 0.5]]
    )
    alive = np.ones((FRAMES, 2), dtype=bool)
    energy, gradient = dynamics_energy(positions, alive, 20.0)
    assert energy == pytest.approx(0.0, abs=1e-18) and np.abs(gradient).max() < 1e-12


def test_terms_have_the_documented_values() -> None:
    scene = Scene(np.array([[[100.0, 100.0]]]), np.array([[1.0]]), 640.0, 480.0, 10.0)
    one = np.array([[[100.0, 100.0]]])
    alive = np.ones((1, 1), dtype=bool)
    # A target on its detection: lambda - s c² / c² = 0.1 - 1.
    assert detection_energy(one, alive, scene, 0.1)[0] == pytest.approx(-0.9)
    two = np.array([[[0.0, 0.0], [3.0, 4.0]]])
    # c² / d² per ordered pair, twice.
    assert exclusion_energy(two, np.ones((1, 2), dtype=bool), 10.0)[0] == pytest.approx(8.0)
    assert regulariser_energy(np.array([[True, False], [True, True]])) == pytest.approx(2 + 0.5 + 1)
