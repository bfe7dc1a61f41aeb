"""``trackfw train classifier``: train the info-less SVM on a dataset.

See docs/algorithms/infoless-classifier.md#svm.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from trackfw.atomic import check_output_file, write_json
from trackfw.errors import UserError
from trackfw.pipeline import parse_assignments
from trackfw_plugins.classifiers.online_rules import OnlineRules

#: Folder beside the model file that keeps the per-video measurements (NPZ).
CACHE_FOLDER = "infoless_features.cache"


def _percent(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{100 * value:.1f}%"


def _check_options(
    flow: str,
    dis_preset: str,
    reference: str,
    replay_rounds: int,
    flow_width: int,
    c_max: float,
    out: Path,
    report: Path | None,
) -> None:
    """Refuse an option outside its choices or an output that cannot be written, in one line."""
    if flow not in ("dis", "farneback"):
        raise UserError(f"--flow {flow!r}: expected 'dis' or 'farneback'.")
    if dis_preset not in ("ultrafast", "fast", "medium"):
        raise UserError(f"--dis-preset {dis_preset!r}: expected ultrafast, fast or medium.")
    if reference not in ("gt", "replay"):
        raise UserError(f"--reference {reference!r}: expected 'gt' or 'replay'.")
    if replay_rounds < 1:
        raise UserError(f"--replay-rounds {replay_rounds}: expected at least 1.")
    if flow_width < 16 or not c_max > 0:
        raise UserError("--flow-width must be at least 16 and --c-max positive.")
    # Training takes minutes: a model or report that cannot be written is said before it.
    check_output_file(out, "--out")
    if report is not None:
        check_output_file(report, "--report")


def _online_rules(
    enter_probability: float,
    leave_probability: float,
    reanchor_after: int,
    reanchor_max_motion: float | None,
    turn_motion: float | None,
    max_hold: int,
) -> OnlineRules:
    """The online rules the options give (None: no limit), refused in one line when invalid."""
    try:
        return OnlineRules(
            enter_probability,
            leave_probability,
            reanchor_after,
            math.inf if reanchor_max_motion is None else reanchor_max_motion,
            turn_motion=math.inf if turn_motion is None else turn_motion,
            max_hold=max_hold,
        )
    except ValueError as error:
        raise UserError(f"the online rule options: {error}.") from None


def _fit(
    train_videos: list[Any],
    settings: Any,
    rules: OnlineRules,
    *,
    select_rules: bool,
    grid: bool,
    seed: int,
    reference: str,
    replay_rounds: int,
    echo: Any,
) -> tuple[Any, Any, OnlineRules, list[dict[str, Any]]]:
    """Choose the online rules (with --select-rules) and fit the SVM; says its cross-validated
    scores. Returns the model, the fit summary, the rules and the rule selection's record."""
    from trackfw_plugins.classifiers.training import fit_model
    from trackfw_plugins.classifiers.training import select_rules as choose_rules

    selection: list[dict[str, Any]] = []
    if select_rules:
        echo("choosing the online rules by cross-validation on the training videos")
        rules, selection = choose_rules(
            train_videos, settings, seed=seed, replay_rounds=replay_rounds, log=echo
        )
        echo(f"chose {rules.as_dict()}")
    model, summary = fit_model(
        train_videos,
        settings,
        grid=grid,
        seed=seed,
        reference=reference,  # type: ignore[arg-type]  # checked by _check_options
        replay_rounds=replay_rounds,
        log=echo,
        rules=rules,
    )
    scores = summary.cross_validated
    # One video has no held-out fold: its scores are in-sample and must not read as validated.
    scored = (
        f"cross-validated ({summary.folds} folds by video"
        if summary.folds >= 2
        else "in-sample (one video: no held-out fold"
    )
    echo(
        f"{scored}, C={summary.C}, gamma={summary.gamma}):"
        f" precision {_percent(scores.precision)}, recall {_percent(scores.recall)},"
        f" F1 {_percent(scores.f1)}"
    )
    return model, summary, rules, selection


def _fit_record(summary: Any, support_vectors: int) -> dict[str, Any]:
    """The fitted hyper-parameters and cross-validated scores, for the model's training record."""
    return {
        "C": summary.C,
        "gamma": summary.gamma,
        "grid": summary.grid,
        "cross_validated": summary.cross_validated.as_dict(),
        "support_vectors": support_vectors,
    }


def _evaluate(
    model: Any, train_videos: list[Any], test_videos: list[Any], flow_width: int, echo: Any
) -> dict[str, Any]:
    """Score the SVM online on the test videos beside the flow threshold fitted on training."""
    from trackfw_plugins.classifiers.training import (
        FrameScores,
        classify_online,
        fit_flow_thresholds,
        flow_threshold_online,
    )

    high, low, _ = fit_flow_thresholds(train_videos, flow_width)
    rows: list[dict[str, Any]] = []
    pooled, pooled_flow = FrameScores(), FrameScores()
    for video in test_videos:
        _, decisions = classify_online(model, video)
        svm_scores = FrameScores.of(decisions, video.labels)
        flow_scores = FrameScores.of(
            flow_threshold_online(video, high, low, flow_width), video.labels
        )
        pooled += svm_scores
        pooled_flow += flow_scores
        rows.append(
            {
                "video": video.name,
                "frames": len(video.frames),
                "svm": svm_scores.as_dict() | {"misclassified": svm_scores.misclassified},
                "flow_threshold": flow_scores.as_dict()
                | {"misclassified": flow_scores.misclassified},
            }
        )
        echo(
            f"  {video.name}: svm P {_percent(svm_scores.precision)} R"
            f" {_percent(svm_scores.recall)} misclassified {svm_scores.misclassified};"
            f" flow-threshold misclassified {flow_scores.misclassified}"
        )
    count = max(len(test_videos), 1)
    for label, scores in (("svm", pooled), (f"flow-threshold ({high}/{low})", pooled_flow)):
        echo(
            f"test {label}: precision {_percent(scores.precision)}, recall"
            f" {_percent(scores.recall)}, F1 {_percent(scores.f1)},"
            f" {scores.misclassified / count:.1f} misclassified frames per video"
        )
    return {
        "videos": rows,
        "svm": pooled.as_dict() | {"misclassified_per_video": pooled.misclassified / count},
        "flow_threshold": pooled_flow.as_dict()
        | {"misclassified_per_video": pooled_flow.misclassified / count},
        "flow_threshold_fitted": {"high": high, "low": low},
    }


def train_classifier(
    dataset: Path,
    out: Path,
    detector: str = "oracle",
    detector_params: list[str] | None = None,
    grid: bool = False,
    seed: int = 0,
    videos_from: Path | None = None,
    evaluate_on: Path | None = None,
    report: Path | None = None,
    flow: str = "dis",
    flow_width: int = 320,
    dis_preset: str = "ultrafast",
    c_max: float = 10.0,
    reference: str = "gt",
    replay_rounds: int = 1,
    cache: bool = True,
    echo: Any = typer.echo,
    enter_probability: float = 0.5,
    leave_probability: float = 0.5,
    reanchor_after: int = 0,
    reanchor_max_motion: float | None = None,
    select_rules: bool = False,
    turn_motion: float | None = None,
    max_hold: int = 300,
) -> dict[str, Any]:
    """Train, optionally evaluate, write the model; returns the report (see the command)."""
    from trackfw_plugins.classifiers.measurements import (
        FeatureSettings,
        collect_measurements,
        read_video_list,
        select_videos,
    )

    _check_options(flow, dis_preset, reference, replay_rounds, flow_width, c_max, out, report)
    rules = _online_rules(
        enter_probability,
        leave_probability,
        reanchor_after,
        reanchor_max_motion,
        turn_motion=turn_motion,
        max_hold=max_hold,
    )
    settings = FeatureSettings(flow, flow_width, dis_preset, c_max)  # type: ignore[arg-type]  # checked above
    spec = {
        "type": detector,
        "params": parse_assignments(detector_params or [], "--detector-param"),
    }
    cache_dir = out.parent / CACHE_FOLDER if cache else None
    train_names = read_video_list(videos_from) if videos_from is not None else None
    train_dirs = select_videos(dataset, train_names)
    echo(f"measuring {len(train_dirs)} training videos with detector {detector!r}")
    train_videos = collect_measurements(train_dirs, spec, settings, cache_dir, echo)
    model, summary, rules, selection = _fit(
        train_videos,
        settings,
        rules,
        select_rules=select_rules,
        grid=grid,
        seed=seed,
        reference=reference,
        replay_rounds=replay_rounds,
        echo=echo,
    )
    model.training = {
        "dataset": str(dataset),
        "videos": [video.name for video in train_videos],
        "frames": int(sum(len(video.frames) for video in train_videos)),
        "detector": spec,
        "seed": seed,
        "reference": reference,
        "replay_rounds": replay_rounds if reference == "replay" else 0,
        **_fit_record(summary, len(model.support_vectors)),
        "online_rules": rules.as_dict(),
        "rule_selection": selection,
    }
    result: dict[str, Any] = {"training": model.training}
    if evaluate_on is not None:
        test_dirs = select_videos(dataset, read_video_list(evaluate_on))
        echo(f"measuring {len(test_dirs)} test videos")
        test_videos = collect_measurements(test_dirs, spec, settings, cache_dir, echo)
        result["test"] = _evaluate(model, train_videos, test_videos, flow_width, echo)
    model.save(out)
    echo(f"wrote {out} ({len(model.support_vectors)} support vectors)")
    if report is not None:
        write_json(report, result)
    return result


# The command's options, one alias each (typer reads them from the signature).
DatasetOption = Annotated[
    Path, typer.Option("--dataset", help="Dataset folder whose videos have intervals.csv.")
]
OutOption = Annotated[Path, typer.Option("--out", help="Model file to write (JSON).")]
DetectorOption = Annotated[
    str, typer.Option("--detector", help="Detector plugin that gives N_t and S_t.")
]
DetectorParamOption = Annotated[
    list[str] | None,
    typer.Option("--detector-param", help="Detector parameter KEY=VALUE (repeatable)."),
]
GridOption = Annotated[
    bool,
    typer.Option("--grid/--no-grid", help="Grid-search C and gamma (GroupKFold by video)."),
]
SeedOption = Annotated[int, typer.Option("--seed", help="Seed of the video folds.")]
VideosFromOption = Annotated[
    Path | None,
    typer.Option("--videos-from", help="Train on the videos named in this file only."),
]
EvaluateOnOption = Annotated[
    Path | None,
    typer.Option(
        "--evaluate-on",
        help="Then score the videos named in this file online, beside flow-threshold.",
    ),
]
ReportOption = Annotated[Path | None, typer.Option("--report", help="Write the scores as JSON.")]
FlowOption = Annotated[str, typer.Option("--flow", help="Optical flow: dis or farneback.")]
FlowWidthOption = Annotated[
    int, typer.Option("--flow-width", help="Working width of the flow, pixels.")
]
DisPresetOption = Annotated[
    str, typer.Option("--dis-preset", help="DIS preset: ultrafast, fast or medium.")
]
CMaxOption = Annotated[float, typer.Option("--c-max", help="Clip of C_t.")]
ReferenceOption = Annotated[
    str,
    typer.Option(
        "--reference",
        help="Reference frame of C_t in training: gt (paper protocol) or replay (gt plus"
        " the features an online replay sees after its own mistakes).",
    ),
]
ReplayRoundsOption = Annotated[
    int, typer.Option("--replay-rounds", help="Rounds of replay with --reference replay.")
]
EnterProbabilityOption = Annotated[
    float,
    typer.Option("--enter-probability", help="Probability that starts an interval (OURS)."),
]
LeaveProbabilityOption = Annotated[
    float,
    typer.Option(
        "--leave-probability",
        help="An interval goes on while the probability is at least this (hysteresis).",
    ),
]
ReanchorAfterOption = Annotated[
    int,
    typer.Option(
        "--reanchor-after",
        help="Consecutive info-less frames after which the C_t reference moves to the"
        " current frame (0: never).",
    ),
]
ReanchorMaxMotionOption = Annotated[
    float | None,
    typer.Option(
        "--reanchor-max-motion",
        help="Re-anchor only when the last 5 M_t are at most this (pixels).",
    ),
]
TurnMotionOption = Annotated[
    float | None,
    typer.Option(
        "--turn-motion",
        help="M_t (pixels) from which a frame is part of a camera turn; an interval begun"
        " by a turn stays open until a second turn ends (default: no latch).",
    ),
]
MaxHoldOption = Annotated[
    int, typer.Option("--max-hold", help="Longest interval the turn latch holds.")
]
SelectRulesOption = Annotated[
    bool,
    typer.Option(
        "--select-rules/--no-select-rules",
        help="Choose the online rules among RULE_CANDIDATES by cross-validation on the"
        " training videos (overrides the rule options above).",
    ),
]
CacheOption = Annotated[
    bool,
    typer.Option(
        "--cache/--no-cache",
        help="Keep per-video measurements beside OUT (infoless_features.cache/).",
    ),
]


def register(train_app: typer.Typer) -> None:
    """Add the ``classifier`` command to the ``trackfw train`` group."""

    @train_app.command("classifier")
    def classifier_command(
        dataset: DatasetOption,
        out: OutOption,
        detector: DetectorOption = "oracle",
        detector_param: DetectorParamOption = None,
        grid: GridOption = False,
        seed: SeedOption = 0,
        videos_from: VideosFromOption = None,
        evaluate_on: EvaluateOnOption = None,
        report: ReportOption = None,
        flow: FlowOption = "dis",
        flow_width: FlowWidthOption = 320,
        dis_preset: DisPresetOption = "ultrafast",
        c_max: CMaxOption = 10.0,
        reference: ReferenceOption = "gt",
        replay_rounds: ReplayRoundsOption = 1,
        enter_probability: EnterProbabilityOption = 0.5,
        leave_probability: LeaveProbabilityOption = 0.5,
        reanchor_after: ReanchorAfterOption = 0,
        reanchor_max_motion: ReanchorMaxMotionOption = None,
        turn_motion: TurnMotionOption = None,
        max_hold: MaxHoldOption = 300,
        select_rules: SelectRulesOption = False,
        cache: CacheOption = True,
    ) -> None:
        """Train the info-less frame SVM (11-d feature, RBF kernel) on a dataset."""
        train_classifier(
            dataset,
            out,
            detector=detector,
            detector_params=detector_param,
            grid=grid,
            seed=seed,
            videos_from=videos_from,
            evaluate_on=evaluate_on,
            report=report,
            flow=flow,
            flow_width=flow_width,
            dis_preset=dis_preset,
            c_max=c_max,
            reference=reference,
            replay_rounds=replay_rounds,
            cache=cache,
            enter_probability=enter_probability,
            leave_probability=leave_probability,
            reanchor_after=reanchor_after,
            reanchor_max_motion=reanchor_max_motion,
            select_rules=select_rules,
            turn_motion=turn_motion,
            max_hold=max_hold,
        )
