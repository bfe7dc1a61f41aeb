"""Training and evaluating the info-less SVM on a dataset.

See docs/algorithms/infoless-classifier.md#svm.

Three steps, each usable on its own:

1. :func:`~trackfw_plugins.classifiers.measurements.measure_video` runs a detector and the optical flow over a video and keeps the raw
   per-frame measurements ``M_t``, ``N_t``, ``S_t`` with the ground-truth labels (cached as NPZ,
   since decoding and flow dominate the cost).
2. :func:`fit_model` builds the training features with the reference frame of ``C_t`` taken from
   the ground truth [OURS], fits ``StandardScaler`` + RBF ``SVC`` (optionally a grid search,
   ``GroupKFold`` by video), fits the Platt sigmoid on out-of-fold decision values and
   cross-validates precision, recall and F1.
3. :func:`classify_online` replays a video frame by frame with the classifier's own decisions
   feeding ``C_t``, exactly as the ``svm`` stage does in the engine, for an honest test score.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.errors import UserError
from trackfw_plugins.classifiers.infoless_features import (
    DEFAULT_C_MAX,
    FEATURE_LAYOUT,
    FeatureAssembler,
)
from trackfw_plugins.classifiers.measurements import (
    FeatureSettings,
    VideoMeasurements,
)
from trackfw_plugins.classifiers.online_rules import OnlineDecider, OnlineRules, model_rules
from trackfw_plugins.classifiers.svm_model import SvmModel, fit_platt, platt_probability
from trackfw_plugins.maths.confusion import LabelCounts

#: Where the reference frame of C_t comes from in training (see :func:`fit_model`).
Reference = Literal["gt", "replay"]

#: The search grid of docs/algorithms/infoless-classifier.md#svm.
GRID_C = (0.1, 1.0, 10.0, 100.0)
GRID_GAMMA: tuple[str | float, ...] = ("scale", 0.01, 0.1, 1.0)


@dataclass
class FrameScores(LabelCounts):
    """Frame-level scores of the info-less label (positive = info-less)."""

    def as_dict(self) -> dict[str, float | None]:
        """Counts and rates, JSON-ready (NaN as None)."""
        values = {
            "tp": self.tp,
            "fp": self.fp,
            "fn": self.fn,
            "tn": self.tn,
            "precision": self.precision,
            "recall": self.recall,
            "f1": self.f1,
        }
        return {
            k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in values.items()
        }


@dataclass
class TrainingReport:
    """What :func:`fit_model` did."""

    C: float
    gamma: str | float
    folds: int
    cross_validated: FrameScores
    grid: list[dict[str, Any]] = field(default_factory=list)


def training_set(
    videos: Sequence[VideoMeasurements], c_max: float = DEFAULT_C_MAX
) -> tuple[FloatArray, IntArray, IntArray]:
    """``(n, 11)`` features, ``(n,)`` labels 0/1 and ``(n,)`` video groups of every frame."""
    features = [video.training_features(c_max) for video in videos]
    labels = [video.labels.astype(np.int64) for video in videos]
    groups = [np.full(len(video.frames), index, np.int64) for index, video in enumerate(videos)]
    return np.concatenate(features), np.concatenate(labels), np.concatenate(groups)


def _pipeline(C: float, gamma: str | float, class_weight: str | None = "balanced") -> Any:
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    return Pipeline(
        [
            ("scaler", StandardScaler()),
            ("svc", SVC(kernel="rbf", C=C, gamma=gamma, class_weight=class_weight)),
        ]
    )


def fit_model(
    videos: Sequence[VideoMeasurements],
    settings: FeatureSettings,
    grid: bool = False,
    seed: int = 0,
    C: float = 1.0,
    gamma: str | float = "scale",
    reference: Reference = "gt",
    replay_rounds: int = 1,
    log: Callable[[str], None] | None = None,
    rules: OnlineRules | None = None,
    class_weight: str | None = "balanced",
) -> tuple[SvmModel, TrainingReport]:
    """Fit the info-less SVM on the videos' frames.

    Args:
        videos: measurements of the training videos (at least one frame of each class).
        settings: the feature settings (recorded in the model).
        grid: search C and gamma on ``GRID_C`` x ``GRID_GAMMA`` by grouped cross-validation (F1).
        seed: shuffles the video folds.
        C, gamma: the SVM's settings without a grid search.
        reference: ``"gt"``: the reference frame of ``C_t`` comes from the ground truth.
            ``"replay"``: in addition, every training video is replayed online by a
            model trained without it, and the features it then saw (its own decisions choosing
            the reference) are added with their true labels. This teaches the SVM the states
            the recursion reaches after its own mistakes (one round of DAgger; Ross et al.
            2011), which ground-truth features never show [OURS].
        replay_rounds: how many times the replay is repeated with the grown training set.
        log: receives progress lines.
        rules: the online rules the replay applies (None: the plain 0.5 decision); the model
            records them and the ``svm`` stage then applies them by default.
        class_weight: the SVC's class weights: ``"balanced"`` (the default) or None (equal) [OURS].

    Returns:
        The model and the report with cross-validated (out-of-fold) frame scores on the
        ground-truth-reference features.
    """
    from sklearn.model_selection import GroupKFold, cross_val_predict

    say = log or (lambda line: None)
    features, labels, groups = training_set(videos, settings.c_max)
    if labels.min() == labels.max():
        raise UserError(
            "the training videos hold only one class of frames; expected both info-less and"
            " informative frames (check intervals.csv)."
        )
    folds = min(5, len(videos))
    grid_rows: list[dict[str, Any]] = []
    if folds >= 2:
        splitter = GroupKFold(n_splits=folds, shuffle=True, random_state=seed)
        if grid:
            C, gamma, grid_rows = _grid_search(
                (features, labels, groups), splitter, C, gamma, class_weight, say
            )
        if reference == "replay":
            features, labels, groups = _add_replayed_rows(
                videos,
                (features, labels, groups),
                splitter,
                (C, gamma, class_weight),
                settings,
                rules,
                replay_rounds,
                say,
            )
        say(f"cross-validating C={C}, gamma={gamma} over {folds} folds grouped by video")
        out_of_fold = cross_val_predict(
            _pipeline(C, gamma, class_weight),
            features,
            labels,
            groups=groups,
            cv=splitter,
            method="decision_function",
        )
    final = _pipeline(C, gamma, class_weight).fit(features, labels)
    if folds < 2:
        # One video: no held-out values; the sigmoid is then fitted in-sample (optimistic).
        out_of_fold = final.decision_function(features)
    platt = fit_platt(out_of_fold, labels.astype(np.float64))
    model = SvmModel.from_sklearn(
        final.named_steps["scaler"],
        final.named_steps["svc"],
        platt=platt,
        feature_layout=FEATURE_LAYOUT,
        features=settings.as_dict() | ({} if rules is None else {"online_rules": rules.as_dict()}),
    )
    original = sum(len(video.frames) for video in videos)
    probabilities = platt_probability(out_of_fold[:original], model.platt_a, model.platt_b)
    scores = FrameScores.of(probabilities >= 0.5, labels[:original].astype(bool))
    return model, TrainingReport(
        C=float(C), gamma=gamma, folds=folds, cross_validated=scores, grid=grid_rows
    )


def _grid_search(
    rows: tuple[FloatArray, IntArray, IntArray],
    splitter: Any,
    C: float,
    gamma: str | float,
    class_weight: str | None,
    say: Callable[[str], None],
) -> tuple[float, str | float, list[dict[str, Any]]]:
    """The best C and gamma on ``GRID_C`` x ``GRID_GAMMA`` by grouped cross-validated F1, and
    every setting's score."""
    from sklearn.model_selection import GridSearchCV

    features, labels, groups = rows
    say(f"grid search over {len(GRID_C) * len(GRID_GAMMA)} settings, {splitter.n_splits} folds")
    search = GridSearchCV(
        _pipeline(C, gamma, class_weight),
        {"svc__C": list(GRID_C), "svc__gamma": list(GRID_GAMMA)},
        scoring="f1",
        cv=splitter,
    )
    search.fit(features, labels, groups=groups)
    grid_rows = [
        {"C": params["svc__C"], "gamma": params["svc__gamma"], "f1": float(score)}
        for params, score in zip(
            search.cv_results_["params"], search.cv_results_["mean_test_score"], strict=True
        )
    ]
    return search.best_params_["svc__C"], search.best_params_["svc__gamma"], grid_rows


def _add_replayed_rows(
    videos: Sequence[VideoMeasurements],
    truth: tuple[FloatArray, IntArray, IntArray],
    splitter: Any,
    svm: tuple[float, str | float, str | None],
    settings: FeatureSettings,
    rules: OnlineRules | None,
    replay_rounds: int,
    say: Callable[[str], None],
) -> tuple[FloatArray, IntArray, IntArray]:
    """The ground-truth rows grown by ``replay_rounds`` rounds of online replay (see
    :func:`fit_model`'s ``reference``); ``svm`` is (C, gamma, class_weight)."""
    features, labels, groups = truth
    C, gamma, class_weight = svm
    for round_number in range(replay_rounds):
        extra_features, extra_labels, extra_groups = _replayed_rows(
            videos,
            (features, labels, groups),
            truth,
            splitter,
            C,
            gamma,
            settings,
            rules,
            class_weight,
        )
        say(
            f"replay round {round_number + 1} added {len(extra_labels)} frames whose C_t"
            " differs online"
        )
        features = np.concatenate([features, extra_features])
        labels = np.concatenate([labels, extra_labels])
        groups = np.concatenate([groups, extra_groups])
    return features, labels, groups


def _replayed_rows(
    videos: Sequence[VideoMeasurements],
    training: tuple[FloatArray, IntArray, IntArray],
    truth: tuple[FloatArray, IntArray, IntArray],
    splitter: Any,
    C: float,
    gamma: str | float,
    settings: FeatureSettings,
    rules: OnlineRules | None = None,
    class_weight: str | None = "balanced",
) -> tuple[FloatArray, IntArray, IntArray]:
    """Features seen online by fold models on their held-out videos, where they differ.

    Args:
        videos: the training videos; group ``i`` is ``videos[i]``.
        training: ``(features, labels, groups)`` the fold models learn from.
        truth: the ground-truth-reference ``(features, labels, groups)``, one row per frame.
        splitter: the grouped cross-validation.
        C, gamma: SVM settings.
        settings: feature settings.
        rules: the online rules of the replay.
        class_weight: the SVC's class weights.
    """
    features, labels, groups = training
    true_features, true_labels, true_groups = truth
    rows: list[FloatArray] = []
    row_labels: list[IntArray] = []
    row_groups: list[IntArray] = []
    for train_rows, test_rows in splitter.split(features, labels, groups):
        fold = _pipeline(C, gamma, class_weight).fit(features[train_rows], labels[train_rows])
        # In-sample sigmoid: only the 0.5 crossing matters for the replay.
        platt = fit_platt(fold.decision_function(features[train_rows]), labels[train_rows])
        fold_model = SvmModel.from_sklearn(
            fold.named_steps["scaler"],
            fold.named_steps["svc"],
            platt=platt,
            feature_layout=FEATURE_LAYOUT,
            features=settings.as_dict(),
        )
        for index in np.unique(groups[test_rows]):
            _, _, seen, latched = replay_with_latch(
                fold_model, videos[int(index)], c_max=settings.c_max, rules=rules or OnlineRules()
            )
            own = true_groups == index
            # Frames the turn latch decided teach nothing: the SVM's answer was not used there.
            differs = np.any(seen != true_features[own], axis=1) & ~latched
            rows.append(seen[differs])
            row_labels.append(true_labels[own][differs])
            row_groups.append(true_groups[own][differs])
    return np.concatenate(rows), np.concatenate(row_labels), np.concatenate(row_groups)


#: Candidate online rules that :func:`select_rules` compares [OURS]: the paper's plain 0.5
#: decision, re-anchoring after 30 info-less frames (alone and with hysteresis), and the turn
#: latch (turns from M_t = 8 or 12 pixels at width 320), alone, with re-anchoring and with a
#: higher entry probability.
RULE_CANDIDATES: tuple[OnlineRules, ...] = (
    OnlineRules(),
    OnlineRules(0.5, 0.5, 30),
    OnlineRules(0.5, 0.35, 30),
    OnlineRules(turn_motion=8.0),
    OnlineRules(0.5, 0.5, 30, turn_motion=8.0),
    OnlineRules(0.7, 0.7, 30, turn_motion=8.0),
    OnlineRules(0.5, 0.5, 30, turn_motion=12.0),
)


def select_rules(
    videos: Sequence[VideoMeasurements],
    settings: FeatureSettings,
    candidates: Sequence[OnlineRules] = RULE_CANDIDATES,
    folds: int = 3,
    seed: int = 0,
    replay_rounds: int = 1,
    log: Callable[[str], None] | None = None,
) -> tuple[OnlineRules, list[dict[str, Any]]]:
    """The candidate with the best online F1 by cross-validation over the training videos.

    For each candidate and each fold (grouped by video), a model is trained with
    ``reference="replay"`` under those rules on the other folds, and the held-out videos are
    replayed online with them, exactly as the ``svm`` stage runs; the pooled frame F1 decides
    (ties: fewer misclassified frames, then the earlier candidate). No test video is seen.

    Returns:
        The chosen rules and one row per candidate (``rules`` and the pooled scores).
    """
    from sklearn.model_selection import GroupKFold

    say = log or (lambda line: None)
    folds = min(folds, len(videos))
    if folds < 2:
        raise UserError("selecting the online rules needs at least two training videos.")
    splitter = GroupKFold(n_splits=folds, shuffle=True, random_state=seed)
    split_rows = list(splitter.split(np.zeros(len(videos)), groups=np.arange(len(videos))))
    rows: list[dict[str, Any]] = []
    best: tuple[float, int] | None = None
    chosen = candidates[0]
    for rules in candidates:
        scores = FrameScores()
        for train_rows, test_rows in split_rows:
            model, _ = fit_model(
                [videos[i] for i in train_rows],
                settings,
                seed=seed,
                reference="replay",
                replay_rounds=replay_rounds,
                rules=rules,
            )
            for i in test_rows:
                _, decisions = classify_online(model, videos[i], rules=rules)
                scores += FrameScores.of(decisions, videos[i].labels)
        f1 = 0.0 if math.isnan(scores.f1) else scores.f1
        rows.append({"rules": rules.as_dict()} | scores.as_dict())
        say(f"rules {rules.as_dict()}: cross-validated online F1 {f1:.3f}")
        key = (f1, -scores.misclassified)
        if best is None or key > best:
            best, chosen = key, rules
    return chosen, rows


# -------------------------------------------------------------------------------- evaluation


def classify_online(
    model: SvmModel,
    video: VideoMeasurements,
    threshold: float | None = None,
    c_max: float | None = None,
    rules: OnlineRules | None = None,
) -> tuple[FloatArray, BoolArray]:
    """Replay the ``svm`` stage over a video's measurements.

    The classifier's own decisions choose the reference frame of ``C_t``; the first frame is
    always informative, as in the engine.

    Args:
        model: the SVM.
        video: the measurements.
        threshold: a plain decision threshold, used when ``rules`` is None.
        c_max: clip of ``C_t``; None for the model's.
        rules: the online rules; None with no ``threshold`` for the model's own (as the
            ``svm`` stage by default).

    Returns:
        ``(T,)`` probabilities and ``(T,)`` info-less decisions.
    """
    probabilities, decisions, _, _ = replay_with_latch(model, video, threshold, c_max, rules)
    return probabilities, decisions


def replay_with_latch(
    model: SvmModel,
    video: VideoMeasurements,
    threshold: float | None = None,
    c_max: float | None = None,
    rules: OnlineRules | None = None,
) -> tuple[FloatArray, BoolArray, FloatArray, BoolArray]:
    """:func:`classify_online` that also returns the ``(T, 11)`` features the stage saw and a
    ``(T,)`` mask of the frames the turn latch decided (not the SVM)."""
    limit = float(model.features.get("c_max", DEFAULT_C_MAX)) if c_max is None else c_max
    assembler = FeatureAssembler(limit)
    if rules is None:
        rules = model_rules(model) if threshold is None else OnlineRules(threshold, threshold)
    decider = OnlineDecider(rules, assembler)
    probabilities = np.zeros(len(video.frames))
    decisions = np.zeros(len(video.frames), dtype=bool)
    latched = np.zeros(len(video.frames), dtype=bool)
    features = np.zeros((len(video.frames), len(FEATURE_LAYOUT)))
    for row, t in enumerate(video.frames):
        features[row] = assembler.push(
            int(t), video.motion[row], video.counts[row], video.spreads[row]
        )
        probabilities[row] = model.probability(features[row])[0]
        decisions[row] = row > 0 and decider.decide(float(probabilities[row]), features[row])
        latched[row] = row > 0 and decider.holding
        decider.settle(int(t), bool(decisions[row]), features[row])
    return probabilities, decisions, features, latched


def flow_threshold_online(
    video: VideoMeasurements, high: float, low: float, flow_width: int
) -> BoolArray:
    """Replay the ``flow-threshold`` stage (thresholds in percent of the width per frame)."""
    motion = 100.0 * video.motion / flow_width
    decisions = np.zeros(len(motion), dtype=bool)
    inside = False
    for row, value in enumerate(motion):
        inside = row > 0 and (value >= low if inside else value > high)
        decisions[row] = inside
    return decisions


def fit_flow_thresholds(
    videos: Sequence[VideoMeasurements], flow_width: int
) -> tuple[float, float, FrameScores]:
    """The ``(high, low)`` pair with the best pooled F1 on ``videos`` (a coarse grid)."""
    candidates = np.round(np.geomspace(0.1, 20.0, 41), 3)
    best: tuple[float, float, FrameScores] | None = None
    for high in candidates:
        for low in candidates[candidates <= high]:
            scores = FrameScores()
            for video in videos:
                scores += FrameScores.of(
                    flow_threshold_online(video, float(high), float(low), flow_width), video.labels
                )
            f1 = 0.0 if math.isnan(scores.f1) else scores.f1
            if best is None or f1 > (0.0 if math.isnan(best[2].f1) else best[2].f1):
                best = (float(high), float(low), scores)
    assert best is not None
    return best


# ------------------------------------------------------------------------------ whole dataset
