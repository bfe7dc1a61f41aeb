"""Tests of the pickle-free SVM model file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from trackfw.errors import UserError
from trackfw_plugins.classifiers.infoless_features import FEATURE_LAYOUT
from trackfw_plugins.classifiers.svm_model import (
    FORMAT_NAME,
    SvmModel,
    fit_platt,
    load_model,
    platt_probability,
)


def toy_data(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    labels = rng.random(count) < 0.3
    features = rng.normal(size=(count, 11)) * [5, 5, 5, 5, 5, 2, 2, 2, 2, 2, 1]
    features[labels, 2:5] += 6.0
    return features, labels.astype(int)


@pytest.fixture(scope="module")
def fitted() -> tuple[StandardScaler, SVC, np.ndarray]:
    features, labels = toy_data(400, 0)
    scaler = StandardScaler().fit(features)
    svc = SVC(kernel="rbf", C=1.0, gamma="scale", class_weight="balanced")
    svc.fit(scaler.transform(features), labels)
    test, _ = toy_data(300, 1)
    return scaler, svc, test


def save_toy(path: Path, fitted: tuple[StandardScaler, SVC, np.ndarray]) -> SvmModel:
    scaler, svc, _ = fitted
    model = SvmModel.from_sklearn(
        scaler, svc, platt=(-1.7, 0.2), feature_layout=FEATURE_LAYOUT, features={"flow": "dis"}
    )
    model.save(path)
    return model


def test_reloaded_model_is_bit_identical_and_matches_sklearn(
    tmp_path: Path, fitted: tuple[StandardScaler, SVC, np.ndarray]
) -> None:
    scaler, svc, test = fitted
    model = save_toy(tmp_path / "model.json", fitted)
    loaded = load_model(tmp_path / "model.json")
    ours = model.decision_function(test)
    assert np.array_equal(loaded.decision_function(test), ours)
    assert np.array_equal(loaded.support_vectors, model.support_vectors)
    reference = svc.decision_function(scaler.transform(test))
    assert np.max(np.abs(ours - reference)) < 1e-9
    assert np.array_equal(ours > 0, reference > 0)
    assert loaded.features == {"flow": "dis"} and loaded.feature_layout == FEATURE_LAYOUT
    assert (loaded.platt_a, loaded.platt_b) == (-1.7, 0.2)


def test_one_row_gives_the_same_bits_as_a_batch(
    tmp_path: Path, fitted: tuple[StandardScaler, SVC, np.ndarray]
) -> None:
    model = save_toy(tmp_path / "model.json", fitted)
    test = fitted[2]
    batch = model.decision_function(test)
    single = np.array([model.decision_function(row)[0] for row in test])
    assert np.array_equal(batch, single)
    probability = model.probability(test)
    assert np.all((probability >= 0) & (probability <= 1))
    assert np.array_equal(probability > 0.5, batch > 0.2 / 1.7)


def test_platt_fit_minimises_the_smoothed_likelihood() -> None:
    rng = np.random.default_rng(3)
    labels = rng.random(500) < 0.4
    decision = np.where(labels, 1.0, -1.0) + rng.normal(scale=1.2, size=500)
    a, b = fit_platt(decision, labels)
    positives, negatives = labels.sum(), (~labels).sum()
    target = np.where(labels, (positives + 1) / (positives + 2), 1 / (negatives + 2))

    def objective(parameters: np.ndarray) -> float:
        probability = platt_probability(decision, parameters[0], parameters[1])
        probability = np.clip(probability, 1e-300, 1 - 1e-16)
        return float(-np.sum(target * np.log(probability) + (1 - target) * np.log(1 - probability)))

    best = minimize(
        objective,
        np.array([0.0, 0.0]),
        method="Nelder-Mead",
        options={"xatol": 1e-8, "fatol": 1e-10},
    )
    assert a < 0
    assert objective(np.array([a, b])) <= best.fun + 1e-6
    assert a == pytest.approx(best.x[0], abs=1e-3) and b == pytest.approx(best.x[1], abs=1e-3)


def damage(path: Path, change: dict) -> Path:
    data = json.loads(path.read_text())
    for dotted, value in change.items():
        target = data
        *parents, last = dotted.split(".")
        for key in parents:
            target = target[key]
        target[last] = value
    damaged = path.with_name("damaged.json")
    damaged.write_text(json.dumps(data))
    return damaged


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"format": "something-else"}, "expected 'trackfw-infoless-svm'"),
        ({"version": 99}, "version is 99"),
        ({"svm.dual_coef": [1.0, 2.0]}, "do not agree"),
        ({"scaler.scale": [0.0] * 11}, "non-positive"),
        ({"svm.gamma": -1.0}, "positive"),
        ({"svm.intercept": "x"}, "svm.intercept"),
        ({"svm.classes": [1, 2]}, "svm.classes"),
        ({"feature_layout": ["a"]}, "feature_layout"),
        ({"platt": None}, "'platt'"),
    ],
)
def test_damaged_files_are_one_user_error(
    tmp_path: Path, fitted: tuple[StandardScaler, SVC, np.ndarray], change: dict, message: str
) -> None:
    save_toy(tmp_path / "model.json", fitted)
    damaged = damage(tmp_path / "model.json", change)
    with pytest.raises(UserError, match=message) as caught:
        load_model(damaged)
    assert len(caught.value.lines) == 1 and str(damaged) in caught.value.lines[0]


def test_non_finite_and_unreadable_files(
    tmp_path: Path, fitted: tuple[StandardScaler, SVC, np.ndarray]
) -> None:
    save_toy(tmp_path / "model.json", fitted)
    text = (tmp_path / "model.json").read_text()
    nan_file = tmp_path / "nan.json"
    nan_file.write_text(
        text.replace('"mean":[', '"mean":[NaN,', 1).replace('"scale":[', '"scale":[1.0,', 1)
    )
    with pytest.raises(UserError, match="non-finite"):
        load_model(nan_file)
    truncated = tmp_path / "truncated.json"
    truncated.write_text(text[: len(text) // 2])
    with pytest.raises(UserError, match="invalid JSON"):
        load_model(truncated)
    with pytest.raises(UserError, match="no such model file"):
        load_model(tmp_path / "missing.json")
    assert FORMAT_NAME in text
