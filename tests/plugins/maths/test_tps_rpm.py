"""Tests of TPS-RPM: reference transcription, transforms, outliers, batching.

See docs/algorithms/tps-rpm.md#algorithm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io

from trackfw_plugins.maths.sinkhorn import SinkhornWorkspace, sinkhorn
from trackfw_plugins.maths.thin_plate import TpsBasis, tps_kernel
from trackfw_plugins.maths.tps_rpm import (
    threshold_matches,
    tps_rpm,
    tps_rpm_batch,
    tps_rpm_multi_batch,
)
from trackfw_plugins.maths.tps_rpm_template import (
    TpsRpmSettings,
    TpsRpmTemplate,
    code_temperatures,
    normalise_points,
)


def _rotation(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def _spread_points(count: int, seed: int, extent: float = 400.0) -> np.ndarray:
    """Random points at least extent/8 apart (well-posed matching)."""
    rng = np.random.default_rng(seed)
    while True:
        points = rng.uniform(0, extent, (count, 2))
        gaps = np.sqrt(np.sum((points[:, None] - points[None]) ** 2, axis=2))
        np.fill_diagonal(gaps, np.inf)
        if gaps.min() > extent / 8:
            return points


def _reference_tps_rpm(template: np.ndarray, data: np.ndarray) -> tuple[np.ndarray, float]:
    """Plain transcription of cMIX ('mix-rpm' normalisation) with separate normalisation."""
    settings = TpsRpmSettings()
    u, _, _ = normalise_points(template)
    w, _, _ = normalise_points(data)
    k, n = len(u), len(w)
    kernel = tps_kernel(u, u)
    v = np.hstack([np.ones((k, 1)), u])
    q, r = np.linalg.qr(v, mode="complete")
    q1, q2, r = q[:, :3], q[:, 3:], r[:3]
    outlier = np.exp(-1) / np.sqrt(np.max(np.sum(u**2, axis=1)))
    x, temperature = u.copy(), settings.T_init
    final = temperature / settings.T_finalfac
    while True:
        for _ in range(settings.perT_maxit):
            m = temperature**-0.5 * np.exp(
                -np.sum((x[:, None] - w[None]) ** 2, axis=2) / temperature
            )
            column_slack, row_slack = np.full(k, outlier), np.full(n, outlier)
            for _ in range(settings.sinkhorn_maxit):
                row_sums = m.sum(axis=1) + column_slack
                m, column_slack = m / row_sums[:, None], column_slack / row_sums
                column_sums = m.sum(axis=0) + row_slack
                m, row_slack = m / column_sums[None], row_slack / column_sums
                error = (np.sum((row_sums - 1) ** 2) + np.sum((column_sums - 1) ** 2)) / (k + n)
                if error < settings.sinkhorn_tol**2:
                    break
            y = np.hstack([np.ones((k, 1)), m @ w / m.sum(axis=1)[:, None]])
            lambda1 = settings.lamda1_init * k * temperature
            lambda2 = settings.lamda2_init * k * temperature
            gamma = np.linalg.solve(q2.T @ kernel @ q2 + lambda1 * np.eye(k - 3), q2.T @ y)
            c = q2 @ gamma
            d = np.eye(3) + np.linalg.solve(
                r.T @ r + lambda2 * np.eye(3), r.T @ q1.T @ (y - kernel @ c) - r.T @ r
            )
            x = (v @ d + kernel @ c)[:, 1:]
        temperature *= settings.anneal_rate
        if temperature < final:
            break
    return m, float(np.trace(c[:, 1:].T @ kernel @ c[:, 1:]))


def test_agrees_with_plain_transcription_of_the_authors_code() -> None:
    rng = np.random.default_rng(0)
    template = _spread_points(7, seed=1)
    data = np.vstack(
        [
            template @ _rotation(0.3).T * 1.3 + 50 + rng.normal(0, 8, (7, 2)),
            rng.uniform(0, 500, (2, 2)),
        ]
    )
    expected_h, expected_energy = _reference_tps_rpm(template, data)
    result = tps_rpm(template, data)
    np.testing.assert_allclose(result.correspondence, expected_h, atol=1e-9)
    assert result.bending_energy == pytest.approx(expected_energy, rel=1e-7, abs=1e-12)


def test_code_schedule_has_86_levels() -> None:
    temperatures = code_temperatures(TpsRpmSettings())
    assert len(temperatures) == 86
    assert temperatures[0] == 0.5
    assert temperatures[-1] >= 0.5 / 500 > temperatures[-1] * 0.93


def test_normalise_points_gives_unit_rms_radius() -> None:
    points = np.random.default_rng(2).normal(300, 40, (9, 2))
    normalised, centre, scale = normalise_points(points)
    assert np.sqrt(np.mean(np.sum(normalised**2, axis=1))) == pytest.approx(1.0)
    np.testing.assert_allclose(centre + scale * normalised, points)
    same, _, unit = normalise_points(np.ones((3, 2)))
    assert unit == 1.0 and np.all(same == 0)


def test_identity_is_recovered() -> None:
    template = _spread_points(8, seed=3)
    result = tps_rpm(template, template)
    assert result.matches.tolist() == [[i, i] for i in range(8)]
    assert result.bending_energy < 1e-8
    np.testing.assert_allclose(result.warped_template, template, atol=1.0)


def test_similarity_transform_is_recovered_with_permuted_data() -> None:
    template = _spread_points(9, seed=4)
    data = template @ _rotation(np.deg2rad(25)).T * 1.7 + np.array([300.0, -120.0])
    permutation = np.random.default_rng(5).permutation(9)
    result = tps_rpm(template, data[permutation])
    truth = np.argsort(permutation)
    assert result.matches[:, 0].tolist() == list(range(9))
    assert result.matches[:, 1].tolist() == truth.tolist()
    assert result.bending_energy < 1e-6
    np.testing.assert_allclose(result.warped_template, data, atol=2.0)


def test_outliers_are_left_unmatched() -> None:
    rng = np.random.default_rng(6)
    template = _spread_points(8, seed=7)
    inliers = template @ _rotation(-0.2).T * 0.8 + 40 + rng.normal(0, 4, (8, 2))
    outliers = np.array([[900.0, 900.0], [-500.0, 700.0], [1200.0, -300.0]])
    result = tps_rpm(template, np.vstack([inliers, outliers]))
    assert result.matches.tolist() == [[i, i] for i in range(8)]


def test_bending_energy_is_zero_for_affine_and_positive_for_bent_maps() -> None:
    template = _spread_points(10, seed=8)
    shear = np.array([[1.2, 0.4], [-0.1, 0.9]])
    affine = tps_rpm(template, template @ shear.T + 10)
    assert affine.bending_energy < 1e-6
    centred = template - template.mean(axis=0)
    bent = template + np.stack([np.zeros(10), 60 * np.sin(centred[:, 0] / 80)], axis=1)
    warped = tps_rpm(template, bent)
    assert len(warped.matches) == 10
    assert warped.bending_energy > 100 * max(affine.bending_energy, 1e-6)


def test_transform_maps_any_point_for_an_affine_pair() -> None:
    template = _spread_points(8, seed=9)
    matrix = np.array([[0.9, -0.3], [0.25, 1.1]])
    result = tps_rpm(template, template @ matrix.T + [20.0, 5.0])
    probes = np.array([[100.0, 100.0], [250.0, 50.0], [10.0, 390.0]])
    np.testing.assert_allclose(result.transform(probes), probes @ matrix.T + [20.0, 5.0], atol=2.0)


def test_batch_equals_single_runs() -> None:
    rng = np.random.default_rng(10)
    template = _spread_points(8, seed=11)
    batch = np.stack(
        [template @ _rotation(a).T + rng.normal(0, 15, (8, 2)) for a in (0.0, 0.2, -0.3, 0.5)]
    )
    batch = np.concatenate([batch, rng.uniform(0, 400, (2, 8, 2))])
    together = tps_rpm_batch(template, batch)
    for data, batched in zip(batch, together, strict=True):
        single = tps_rpm(template, data)
        np.testing.assert_allclose(batched.correspondence, single.correspondence, atol=1e-12)
        np.testing.assert_array_equal(batched.matches, single.matches)
        assert batched.bending_energy == pytest.approx(single.bending_energy, rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(batched.warped_template, single.warped_template, atol=1e-9)


def test_multi_template_batch_equals_single_runs() -> None:
    rng = np.random.default_rng(12)
    templates = [_spread_points(8, seed=s) for s in (13, 14)]
    data = rng.uniform(0, 400, (5, 9, 2))
    prepared = [TpsRpmTemplate(t) for t in templates]
    owner = np.array([1, 0, 1, 0, 0])
    outputs = tps_rpm_multi_batch(prepared, owner, data)
    for index in range(5):
        single = tps_rpm(templates[owner[index]], data[index])
        np.testing.assert_allclose(outputs.correspondence[index], single.correspondence, atol=1e-12)
        assert outputs.result(index, prepared).matches.tolist() == single.matches.tolist()


def test_three_or_fewer_points_use_the_affine_part_only() -> None:
    template = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 50.0]])
    result = tps_rpm(template, template * 1.5 + 7)
    assert result.bending_energy == 0.0
    assert np.all(result.nonaffine == 0)
    assert result.matches.tolist() == [[0, 0], [1, 1], [2, 2]]


def test_threshold_matches_is_one_to_one() -> None:
    h = np.array([[0.7, 0.6, 0.0], [0.8, 0.1, 0.0], [0.0, 0.0, 0.4]])
    assert threshold_matches(h).tolist() == [[1, 0]]
    assert threshold_matches(h, 0.3).tolist() == [[1, 0], [2, 2]]


def test_empty_inputs_give_no_matches() -> None:
    template = _spread_points(5, seed=15)
    result = tps_rpm(template, np.zeros((0, 2)))
    assert result.correspondence.shape == (5, 0) and len(result.matches) == 0
    np.testing.assert_allclose(result.transform(template), template)


@pytest.mark.parametrize(
    "settings",
    [
        TpsRpmSettings(mode="mixture"),
        TpsRpmSettings(early_stop=True),
        TpsRpmSettings(precision="float32"),
        TpsRpmSettings(noise_seed=3),
    ],
)
def test_options_still_recover_a_similarity(settings: TpsRpmSettings) -> None:
    template = _spread_points(8, seed=16)
    data = template @ _rotation(0.15).T * 1.2 + 30
    result = tps_rpm(template, data, settings)
    assert result.matches.tolist() == [[i, i] for i in range(8)]


def test_float32_agrees_with_float64() -> None:
    rng = np.random.default_rng(17)
    template = _spread_points(8, seed=18)
    data = rng.uniform(0, 400, (9, 2))
    exact = tps_rpm(template, data)
    fast = tps_rpm(template, data, TpsRpmSettings(precision="float32"))
    np.testing.assert_allclose(fast.correspondence, exact.correspondence, atol=1e-3)
    assert fast.bending_energy == pytest.approx(exact.bending_energy, rel=1e-3, abs=1e-6)


def test_noise_seed_is_deterministic() -> None:
    template = _spread_points(8, seed=19)
    data = np.random.default_rng(20).uniform(0, 400, (9, 2))
    settings = TpsRpmSettings(noise_seed=7)
    first = tps_rpm(template, data, settings)
    second = tps_rpm(template, data, settings)
    np.testing.assert_array_equal(first.correspondence, second.correspondence)


def test_paper_schedule_runs_and_keeps_the_identity() -> None:
    template = _spread_points(8, seed=21)
    result = tps_rpm(template, template + 5, TpsRpmSettings(schedule="paper"))
    assert result.correspondence.shape == (8, 8)
    # Far from binary on sparse sets (the CVIU schedule), but the largest entry of each row is correct.
    assert np.argmax(result.correspondence, axis=1).tolist() == list(range(8))


def test_thin_plate_fit_interpolates_without_regularisation() -> None:
    points = _spread_points(7, seed=22)
    targets = points + np.random.default_rng(23).normal(0, 20, (7, 2))
    basis = TpsBasis.from_template(points)
    c, d = basis.fit(targets, 1e-9, 1e-9)
    np.testing.assert_allclose(basis.evaluate(points, c, d), targets, atol=1e-3)
    assert basis.bending_energy(c) > 0


def _correct_rate(path: Path) -> float:
    sample = scipy.io.loadmat(path)
    template, data = sample["x1"], sample["y2a"]
    ground_truth = min(len(sample["y2"]), len(data))
    matches = tps_rpm(template, data).matches
    correct = (matches[:, 0] < ground_truth) & (matches[:, 0] == matches[:, 1])
    return float(correct.sum() / ground_truth)


@pytest.mark.parametrize(
    ("name", "minimum"),
    [
        ("save_fish_def_1_1.mat", 0.95),
        ("save_fish_def_5_2.mat", 0.95),
        ("save_chinese_def_1_1.mat", 0.95),
        ("save_fish_outlier_3_2.mat", 0.85),
        ("save_chinese_outlier_3_1.mat", 0.85),
    ],
)
def test_chui_rangarajan_correct_correspondence(
    shared_data: Path, name: str, minimum: float
) -> None:
    path = shared_data / "pointsets" / "chui_rangarajan_synthetic" / name
    if not path.is_file():
        pytest.skip(f"{path} not found")
    assert _correct_rate(path) >= minimum


@pytest.mark.parametrize(
    ("precision", "energies"),
    [
        ("float32", [0.0, 0.601489085, 1.345115419, 0.457005496, 0.747012388]),
        ("float64", [0.0, 0.601489217, 1.345115504, 0.457005479, 0.747012398]),
    ],
)
def test_multi_batch_is_pinned_to_the_reference_implementation(
    precision: str, energies: list[float]
) -> None:
    # Outputs of the implementation before the speed work (November 2026), pinned so that
    # optimisations of the annealing loop keep the matches and φ to 1e-6.
    rng = np.random.default_rng(7)
    templates = [rng.uniform(0, 300, (8, 2)) for _ in range(2)]
    data = rng.uniform(0, 300, (5, 9, 2))
    data[0, :8] = templates[0] * 1.1 + 20
    settings = TpsRpmSettings(precision=precision)
    outputs = tps_rpm_multi_batch(
        [TpsRpmTemplate(points, settings) for points in templates], np.array([0, 0, 1, 1, 1]), data
    )
    assert outputs.matched.tolist() == [
        [0, 1, 2, 3, 4, 5, 6, 7],
        [5, 6, 0, 1, 3, 8, 2, 7],
        [0, 8, -1, 5, 3, 2, 1, 7],
        [7, 3, 6, -1, 5, 8, 0, -1],
        [3, 4, 2, 0, 8, 5, 7, 1],
    ]
    np.testing.assert_allclose(outputs.bending_energy, energies, rtol=0, atol=1e-6)


def _plainsinkhorn(
    affinity: np.ndarray,
    row_slack: float,
    column_slack: float,
    max_sweeps: int,
    tolerance: float,
    initial_row_scale: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One data set, written as the code's loop: scalings after the stopping sweep."""
    rows, columns = affinity.shape
    row_scale = np.full(rows, initial_row_scale)
    column_scale = np.ones(columns)
    for _ in range(max_sweeps):
        row_sums = row_scale * (affinity @ column_scale + row_slack)
        row_scale = row_scale / row_sums
        column_sums = column_scale * (affinity.T @ row_scale + column_slack)
        column_scale = column_scale / column_sums
        error = np.sum((row_sums - 1) ** 2) + np.sum((column_sums - 1) ** 2)
        if error < tolerance * tolerance * (rows + columns):
            break
    return row_scale, column_scale


@pytest.mark.parametrize("with_workspace", [False, True])
def test_batched_sinkhorn_equals_one_data_set_at_a_time(with_workspace: bool) -> None:
    # Data sets of very different sharpness stop at sweeps 2 to 8, which exercises the
    # history slabs and the final gather of each data set's stopping sweep.
    rng = np.random.default_rng(3)
    rows, columns, batch = 5, 6, 40
    sharpness = np.linspace(0.2, 30.0, batch)
    affinity = np.exp(-sharpness * rng.uniform(0, 1, (rows, columns, batch)))
    row_slack = rng.uniform(0.05, 0.3, batch)
    column_slack = rng.uniform(0.05, 0.3, batch)
    workspace = SinkhornWorkspace(rows, columns, batch, 10, np.float64) if with_workspace else None
    for _ in range(2):  # a reused workspace must not leak state between calls
        row_scale, column_scale = sinkhorn(
            affinity, row_slack, column_slack, 10, 0.05, 1.7, workspace
        )
        for index in range(batch):
            expected_row, expected_column = _plainsinkhorn(
                affinity[:, :, index], row_slack[index], column_slack[index], 10, 0.05, 1.7
            )
            np.testing.assert_allclose(row_scale[:, index], expected_row, rtol=1e-12)
            np.testing.assert_allclose(column_scale[:, index], expected_column, rtol=1e-12)
