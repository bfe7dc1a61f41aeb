"""The info-less SVM as a JSON file: no pickle, no scikit-learn needed at inference.

A model is ``StandardScaler`` followed by a binary RBF ``SVC``
(docs/algorithms/infoless-classifier.md#svm) plus a Platt
sigmoid that maps the decision value to a probability. The file stores exactly what the
decision function needs::

    f(x) = sum_i alpha_i * exp(-gamma * ||z - s_i||^2) + intercept,   z = (x - mean) / scale
    p(x) = 1 / (1 + exp(A * f(x) + B))                                  (Platt 1999)

``alpha_i`` are scikit-learn's ``dual_coef_`` (sign already folded in), ``s_i`` the support
vectors in scaled space, and ``f > 0`` means class 1 (info-less). JSON writes floats with
Python's shortest round-trip representation, so a saved and reloaded model holds the very same
doubles, and the numpy evaluation below (element-wise operations and row sums, no BLAS whose
blocking could depend on the batch size) gives bit-identical values on every call, whether one
frame or many are evaluated.

Probabilities: scikit-learn's ``SVC(probability=True)`` fits Platt's sigmoid on an internal,
randomly shuffled cross-validation, which is not reproducible; training instead fits A and B
itself with :func:`fit_platt` on out-of-fold decision values (grouped by video).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.atomic import write_text
from trackfw.errors import UserError

FORMAT_NAME = "trackfw-infoless-svm"
FORMAT_VERSION = 1
#: Rows evaluated at once: bounds the (rows, support vectors, features) temporary array.
_CHUNK_ROWS = 256


@dataclass
class SvmModel:
    """A fitted scaler + RBF SVM + Platt sigmoid.

    Attributes:
        mean: ``(D,)`` scaler mean.
        scale: ``(D,)`` scaler scale (positive).
        support_vectors: ``(S, D)`` support vectors in scaled space.
        dual_coef: ``(S,)`` signed dual coefficients (positive pulls towards class 1).
        intercept: the decision function's intercept.
        gamma: RBF kernel width.
        platt_a, platt_b: Platt sigmoid ``p = 1 / (1 + exp(A f + B))``.
        classes: the two class labels; ``classes[1]`` (info-less) is the positive one.
        feature_layout: name of each of the D feature dimensions.
        features: how the features were computed (flow method, width, c_max...).
        training: free-form, JSON-serialisable record of how the model was trained.
    """

    mean: FloatArray
    scale: FloatArray
    support_vectors: FloatArray
    dual_coef: FloatArray
    intercept: float
    gamma: float
    platt_a: float = -1.0
    platt_b: float = 0.0
    classes: tuple[int, int] = (0, 1)
    feature_layout: tuple[str, ...] = ()
    features: dict[str, Any] = field(default_factory=dict)
    training: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_sklearn(
        cls, scaler: Any, svc: Any, platt: tuple[float, float] = (-1.0, 0.0), **extra: Any
    ) -> SvmModel:
        """Copy a fitted ``StandardScaler`` and binary RBF ``SVC``.

        Args:
            scaler: fitted ``sklearn.preprocessing.StandardScaler``.
            svc: fitted ``sklearn.svm.SVC`` with ``kernel="rbf"`` and two classes.
            platt: ``(A, B)`` of the sigmoid.
            **extra: ``feature_layout``, ``features``, ``training``.
        """
        if svc.kernel != "rbf" or len(svc.classes_) != 2:
            raise ValueError("only a binary SVC with an RBF kernel can be stored")
        return cls(
            mean=np.asarray(scaler.mean_, dtype=np.float64).copy(),
            scale=np.asarray(scaler.scale_, dtype=np.float64).copy(),
            support_vectors=np.asarray(svc.support_vectors_, dtype=np.float64).copy(),
            dual_coef=np.asarray(svc.dual_coef_, dtype=np.float64).reshape(-1).copy(),
            intercept=float(np.asarray(svc.intercept_).reshape(-1)[0]),
            gamma=float(svc._gamma),  # the resolved value of gamma="scale"
            platt_a=float(platt[0]),
            platt_b=float(platt[1]),
            classes=(int(svc.classes_[0]), int(svc.classes_[1])),
            **extra,
        )

    @property
    def n_features(self) -> int:
        """Dimension D of the feature vector."""
        return len(self.mean)

    def decision_function(self, features: FloatArray) -> FloatArray:
        """Signed distance ``f`` of ``(n, D)`` features (or one ``(D,)`` vector) -> ``(n,)``."""
        rows = np.asarray(features, dtype=np.float64).reshape(-1, self.n_features)
        scaled = (rows - self.mean) / self.scale
        values = np.empty(len(rows), dtype=np.float64)
        for start in range(0, len(rows), _CHUNK_ROWS):
            chunk = scaled[start : start + _CHUNK_ROWS]
            difference = chunk[:, None, :] - self.support_vectors[None, :, :]
            kernel = np.exp(-self.gamma * np.sum(difference * difference, axis=2))
            values[start : start + len(chunk)] = np.sum(kernel * self.dual_coef, axis=1)
        return values + self.intercept

    def probability(self, features: FloatArray) -> FloatArray:
        """Platt probability that each of ``(n, D)`` features is info-less -> ``(n,)``."""
        return platt_probability(self.decision_function(features), self.platt_a, self.platt_b)

    def to_json(self) -> dict[str, Any]:
        """The model as a JSON-serialisable dict (the file format)."""
        return {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "feature_layout": list(self.feature_layout),
            "features": self.features,
            "scaler": {"mean": self.mean.tolist(), "scale": self.scale.tolist()},
            "svm": {
                "kernel": "rbf",
                "gamma": self.gamma,
                "intercept": self.intercept,
                "classes": list(self.classes),
                "dual_coef": self.dual_coef.tolist(),
                "support_vectors": self.support_vectors.tolist(),
            },
            "platt": {"a": self.platt_a, "b": self.platt_b},
            "training": self.training,
        }

    def save(self, path: str | Path) -> None:
        """Write the model to ``path`` atomically as compact JSON."""
        text = json.dumps(self.to_json(), separators=(",", ":"), allow_nan=False)
        write_text(path, text + "\n")


def platt_probability(decision: FloatArray, a: float, b: float) -> FloatArray:
    """``1 / (1 + exp(a f + b))`` computed without overflow.

    >>> platt_probability(np.array([0.0, 1000.0, -1000.0]), -2.0, 0.0).tolist()
    [0.5, 1.0, 0.0]
    """
    z = a * np.asarray(decision, dtype=np.float64) + b
    # exp of a large positive z overflows; use exp(-z)/(1+exp(-z)) there instead.
    positive = z >= 0
    result = np.empty_like(z)
    exp_negative = np.exp(-z[positive])
    result[positive] = exp_negative / (1.0 + exp_negative)
    result[~positive] = 1.0 / (1.0 + np.exp(z[~positive]))
    return result


def fit_platt(
    decision: FloatArray, labels: FloatArray, max_iterations: int = 100
) -> tuple[float, float]:
    """Fit Platt's sigmoid ``p = 1 / (1 + exp(A f + B))`` to decision values and 0/1 labels.

    Newton's method with backtracking and Platt's smoothed targets, as in Lin, Lin & Weng, "A
    note on Platt's probabilistic outputs for support vector machines" (Machine Learning 2007),
    the algorithm libsvm uses. Deterministic.

    Args:
        decision: ``(n,)`` decision values (preferably out-of-fold).
        labels: ``(n,)`` labels, 1 for the positive class.
        max_iterations: Newton iterations.

    Returns:
        ``(A, B)``; A is negative when larger decision values mean class 1.

    >>> a, b = fit_platt(np.array([-2.0, -1.0, 1.0, 2.0]), np.array([0, 0, 1, 1]))
    >>> a < 0, abs(b) < 1e-9
    (True, True)
    """
    f = np.asarray(decision, dtype=np.float64)
    y = np.asarray(labels).astype(bool)
    positives = float(np.count_nonzero(y))
    negatives = float(len(y) - positives)
    high = (positives + 1.0) / (positives + 2.0)
    low = 1.0 / (negatives + 2.0)
    target = np.where(y, high, low)
    a, b = 0.0, math.log((negatives + 1.0) / (positives + 1.0))
    sigma, minimum_step, epsilon = 1e-12, 1e-10, 1e-5

    def objective(a_value: float, b_value: float) -> float:
        z = f * a_value + b_value
        # sum of t*z + log(1 + exp(-z)), written stably for both signs of z.
        linear = np.where(z >= 0, target * z, (target - 1.0) * z)
        return float(np.sum(linear + np.log1p(np.exp(-np.abs(z)))))

    value = objective(a, b)
    for _ in range(max_iterations):
        p = platt_probability(f, a, b)  # = 1/(1+exp(z))
        q = 1.0 - p
        d2 = p * q
        h11 = sigma + float(np.sum(f * f * d2))
        h22 = sigma + float(np.sum(d2))
        h21 = float(np.sum(f * d2))
        d1 = target - p
        g1 = float(np.sum(f * d1))
        g2 = float(np.sum(d1))
        if abs(g1) < epsilon and abs(g2) < epsilon:
            break
        determinant = h11 * h22 - h21 * h21
        delta_a = -(h22 * g1 - h21 * g2) / determinant
        delta_b = -(-h21 * g1 + h11 * g2) / determinant
        slope = g1 * delta_a + g2 * delta_b
        step = 1.0
        while step >= minimum_step:
            new_a, new_b = a + step * delta_a, b + step * delta_b
            new_value = objective(new_a, new_b)
            if new_value < value + 1e-4 * step * slope:
                a, b, value = new_a, new_b, new_value
                break
            step /= 2.0
        else:
            break  # line search failed: keep the best point found
    return a, b


# ------------------------------------------------------------------------------------- loading


def _array(path: Path, data: Any, name: str, ndim: int) -> FloatArray:
    try:
        array = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserError(
            f"{path}: {name} is not an array of numbers; expected a list of numbers."
        ) from None
    if array.ndim != ndim:
        raise UserError(f"{path}: {name} has {array.ndim} dimensions; expected {ndim}.")
    if not np.all(np.isfinite(array)):
        raise UserError(f"{path}: {name} holds non-finite values; expected finite numbers.")
    return array


def _number(path: Path, data: Any, name: str) -> float:
    if isinstance(data, bool) or not isinstance(data, int | float) or not math.isfinite(data):
        raise UserError(f"{path}: {name} is {data!r}; expected a finite number.")
    return float(data)


def _section(path: Path, data: Any, name: str) -> dict[str, Any]:
    value = data.get(name) if isinstance(data, dict) else None
    if not isinstance(value, dict):
        raise UserError(
            f"{path}: the field {name!r} is missing or not an object;"
            f" expected a {FORMAT_NAME} model."
        )
    return value


def _read_model_json(path: Path) -> dict[str, Any]:
    """The file's JSON object, checked to be this format at this version."""
    if not path.is_file():
        raise UserError(f"{path}: no such model file; expected a {FORMAT_NAME} JSON file.")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise UserError(f"{path}: not UTF-8 text; expected a {FORMAT_NAME} JSON file.") from None
    except json.JSONDecodeError as error:
        raise UserError(
            f"{path}: line {error.lineno}: invalid JSON ({error.msg});"
            f" expected a {FORMAT_NAME} file."
        ) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise UserError(f"{path}: format is {found!r}; expected {FORMAT_NAME!r}.")
    if data.get("version") != FORMAT_VERSION:
        raise UserError(
            f"{path}: version is {data.get('version')!r}; expected {FORMAT_VERSION} (retrain or"
            " upgrade trackfw)."
        )
    return data


def load_model(path: str | Path) -> SvmModel:
    """Read and check a model file; any problem is one :class:`UserError` sentence."""
    path = Path(path)
    data = _read_model_json(path)
    scaler, svm, platt = (_section(path, data, name) for name in ("scaler", "svm", "platt"))
    if svm.get("kernel") != "rbf":
        raise UserError(f"{path}: svm.kernel is {svm.get('kernel')!r}; expected 'rbf'.")
    mean = _array(path, scaler.get("mean"), "scaler.mean", 1)
    scale = _array(path, scaler.get("scale"), "scaler.scale", 1)
    vectors = _array(path, svm.get("support_vectors"), "svm.support_vectors", 2)
    dual = _array(path, svm.get("dual_coef"), "svm.dual_coef", 1)
    dimension = len(mean)
    if dimension == 0 or scale.shape != (dimension,) or np.any(scale <= 0):
        raise UserError(
            f"{path}: scaler.scale has shape {scale.shape} or non-positive values; expected"
            f" {dimension} positive numbers like scaler.mean."
        )
    if vectors.shape[1:] != (dimension,) or len(vectors) == 0 or dual.shape != (len(vectors),):
        raise UserError(
            f"{path}: svm.support_vectors {vectors.shape} and svm.dual_coef {dual.shape} do not"
            f" agree; expected (S, {dimension}) and (S,) with S > 0."
        )
    layout = data.get("feature_layout", [])
    if not isinstance(layout, list) or len(layout) != dimension:
        raise UserError(
            f"{path}: feature_layout has not {dimension} names; expected one per feature."
        )
    classes = svm.get("classes")
    if classes != [0, 1]:
        raise UserError(f"{path}: svm.classes is {classes!r}; expected [0, 1] (1 = info-less).")
    features = data.get("features", {})
    training = data.get("training", {})
    if not isinstance(features, dict) or not isinstance(training, dict):
        raise UserError(f"{path}: features and training must be JSON objects.")
    gamma = _number(path, svm.get("gamma"), "svm.gamma")
    if gamma <= 0:
        raise UserError(f"{path}: svm.gamma is {gamma}; expected a positive number.")
    return SvmModel(
        mean=mean,
        scale=scale,
        support_vectors=vectors,
        dual_coef=dual,
        intercept=_number(path, svm.get("intercept"), "svm.intercept"),
        gamma=gamma,
        platt_a=_number(path, platt.get("a"), "platt.a"),
        platt_b=_number(path, platt.get("b"), "platt.b"),
        classes=(0, 1),
        feature_layout=tuple(str(name) for name in layout),
        features=features,
        training=training,
    )
