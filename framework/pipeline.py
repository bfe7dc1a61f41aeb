"""Pipelines: YAML files that name one plugin per stage kind, with its parameters.

Loading is strict and reports every problem at once, one line each, as
``FILE: YAML.PATH: what was expected``. YAML is read by :mod:`trackfw.yaml_loading`
(``yaml.safe_load`` semantics, bounded alias expansion, no duplicate keys). Validation builds
every stage, so a missing model file is found before the first frame is read.
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, cast

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from trackfw.errors import UserError, quoted
from trackfw.registry import Registry, unknown_name_message
from trackfw.stages import (
    BATCH_KINDS,
    NESTED_KINDS,
    STAGE_KINDS,
    BatchStages,
    FiniteModel,
    PipelineStages,
    Stage,
    StageParams,
)
from trackfw.yaml_loading import YamlTooLargeError, parse_yaml, safe_load

TOP_LEVEL_KEYS = ("name", "description", "input", "stages", "engine")
#: Every kind a pipeline's ``stages`` may name: the segment kinds, then the batch tracker.
PIPELINE_KINDS = (*STAGE_KINDS, "batch_tracker")
STAGE_KEYS = ("type", "params")


class EngineOptions(FiniteModel):
    """Options of the online loop itself (``engine:`` in a pipeline)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    box_size: float = Field(
        80.0,
        gt=0,
        description="side in pixels of the box written around each head point in tracks.txt (the MOT-text convention: a head at 1080p)",
    )
    init: str = Field(
        "auto",
        pattern="^(auto|gt|detections|region|targets)$",
        description="where the targets come from, on the start frame: 'gt' (gt.csv, as the paper), 'detections' (every detection), 'region' (the detections inside engine.region), 'targets' (the file engine.targets), 'auto' (gt when present, else detections)",
    )
    region: tuple[float, float, float, float] | None = Field(
        None,
        description="init: region: the box x,y,w,h in pixels whose detections (head points) become the targets",
    )
    targets: str | None = Field(
        None,
        description="init: targets: a file of target points, rows frame,id,x,y under that header, or MOTChallenge text whose boxes become head points; the run starts on its first frame",
    )
    start_frame: int | None = Field(
        None,
        ge=1,
        description="1-based frame on which the targets are chosen (nothing is reported before it); null: the first readable frame, or with init: targets the file's first frame",
    )
    fill_missing_s: float | None = Field(
        None,
        ge=0.0,
        description="after the video, a target not reported for at most this long (seconds) between two frames of one segment where it is, is reported on the frames between, on the straight line from one of those points to the other (offline, as ByteTrack interpolates); null = off, the loop's reports as they were made",
    )
    fill_after_b_s: float | None = Field(
        None,
        ge=0.0,
        description="after the video, a target first reported at most this long (seconds) after a frame b is reported from b on, on the straight line fitted to its reports of the same length of time from its first one, carried back; null = off",
    )
    fill_after_b_min_reports: int = Field(
        1,
        ge=1,
        description="fill_after_b_s: a target needs at least this many reports within fill_after_b_s of its first one to be reported from b on (1: a single report is held still back to b; 2: a line is needed, as real.yaml)",
    )
    infoless_frames: Literal["keep", "drop"] = Field(
        "keep",
        description="batch pipelines: 'keep' gives the batch tracker every frame's detections, info-less frames included (the paper's protocol); 'drop' leaves out the frames the classifier calls info-less",
    )

    @field_validator("region")
    @classmethod
    def _positive_box(
        cls, region: tuple[float, float, float, float] | None
    ) -> tuple[float, float, float, float] | None:
        if region is not None and (region[2] <= 0 or region[3] <= 0):
            raise ValueError(f"width and height are {region[2]:g} and {region[3]:g}; expected > 0")
        return region

    @model_validator(mode="after")
    def _mode_has_its_input(self) -> EngineOptions:
        for mode in ("region", "targets"):
            given = getattr(self, mode) is not None
            if self.init == mode and not given:
                raise ValueError(f"init is {mode!r} and {mode} is not set; expected both")
            if given and self.init != mode:
                raise ValueError(f"{mode} is set and init is {self.init!r}; expected init: {mode}")
        return self


@dataclass(frozen=True)
class StageConfig:
    """A validated stage: its class, its parameter model and the stages configured inside it.

    Attributes:
        kind: the stage kind (``detector``, ..., or ``predictor`` for a nested stage).
        name: the plugin name (YAML ``type``).
        cls: the registered class.
        params: the validated, fully defaulted parameters (an instance of ``cls.Params``).
        nested: parameter name -> nested stage (a gap matcher's ``predictor``).
    """

    kind: str
    name: str
    cls: type[Stage[Any]]
    params: StageParams
    nested: dict[str, StageConfig] = field(default_factory=dict)

    def build(self) -> Stage[Any]:
        """A fresh instance (nested stages built first) from the already validated parameters."""
        return self.cls(self.params, **{key: spec.build() for key, spec in self.nested.items()})

    def as_data(self) -> dict[str, Any]:
        """``{"type", "params"}`` as plain data, nested stages in the same shape (YAML-ready)."""
        params = self.params.model_dump(mode="json")
        params.update({key: spec.as_data() for key, spec in self.nested.items()})
        return {"type": self.name, "params": params}


@dataclass
class Pipeline:
    """A validated pipeline.

    Attributes:
        name: the pipeline's name.
        description: free text.
        input: default input (``builtin:NAME`` or a path), or None.
        stages: kind -> validated stage configuration.
        engine: options of the online loop.
        source: the YAML file, or None when built in memory.
    """

    name: str
    description: str
    input: str | None
    stages: dict[str, StageConfig]
    engine: EngineOptions
    source: Path | None = None

    @property
    def config(self) -> dict[str, Any]:
        """The complete configuration as plain data (hashing, summary.json, bench jobs).

        It validates again to the same pipeline: ``validate_pipeline(config)``.
        """
        return {
            "name": self.name,
            "stages": {kind: spec.as_data() for kind, spec in self.stages.items()},
            "engine": self.engine.model_dump(),
        }

    @property
    def content_hash(self) -> str:
        """Short hash of the resolved configuration (same config -> same hash)."""
        canonical = json.dumps(self.config, sort_keys=True, default=str)
        return hashlib.sha256(canonical.encode()).hexdigest()[:12]

    @property
    def is_batch(self) -> bool:
        """True for a batch pipeline (detector + batch tracker), False for a segment pipeline."""
        return "batch_tracker" in self.stages

    def build(self) -> PipelineStages | BatchStages:
        """Fresh stage instances, one per kind (call once per video)."""
        return self.build_batch() if self.is_batch else self.build_segment()

    def build_segment(self) -> PipelineStages:
        """Fresh stages of a segment pipeline (call once per video).

        Raises:
            TypeError: this is a batch pipeline.
        """
        if self.is_batch:
            raise TypeError(f"pipeline {self.name!r} is a batch pipeline, not a segment one")
        return PipelineStages(**self._built())

    def build_batch(self) -> BatchStages:
        """Fresh stages of a batch pipeline (call once per video).

        Raises:
            TypeError: this is a segment pipeline.
        """
        if not self.is_batch:
            raise TypeError(f"pipeline {self.name!r} is not a batch pipeline")
        return BatchStages(**self._built())

    def _built(self) -> dict[str, Any]:
        # resolve_stage checked each class against its kind's base when it was registered.
        return cast(dict[str, Any], {kind: spec.build() for kind, spec in self.stages.items()})


def parse_assignments(assignments: list[str], option: str) -> dict[str, Any]:
    """``["k=v", ...]`` to a dict; values are read as YAML scalars (numbers, booleans...).

    >>> parse_assignments(["miss_rate=0.1", "source=heads"], "--detector-param")
    {'miss_rate': 0.1, 'source': 'heads'}
    """
    params: dict[str, Any] = {}
    for assignment in assignments:
        key, separator, text = assignment.partition("=")
        if not separator or not key.strip():
            raise UserError(f"{option} {quoted(assignment)}: expected KEY=VALUE.")
        try:
            params[key.strip()] = safe_load(text) if text.strip() else ""
        except YamlTooLargeError as error:
            raise UserError(f"{option} {quoted(assignment)}: {error.problem}.") from None
        except yaml.YAMLError:
            raise UserError(
                f"{option} {quoted(assignment)}: the value is not valid YAML."
            ) from None
    return params


def apply_overrides(data: dict[str, Any], overrides: Sequence[str], source: str) -> list[str]:
    """Apply ``path.to.key=value`` overrides in place; returns problems (one line each)."""
    problems: list[str] = []
    for override in overrides:
        path, separator, raw_value = override.partition("=")
        keys = [key for key in path.strip().split(".") if key]
        if not separator or not keys:
            problems.append(
                f"--set {quoted(override)}: expected PATH=VALUE, e.g. stages.tracker.params.gate_px=40"
            )
            continue
        try:
            value = safe_load(raw_value) if raw_value.strip() else ""
        except YamlTooLargeError as error:
            problems.append(f"--set {quoted(override)}: {error.problem}")
            continue
        except yaml.YAMLError:
            value = raw_value
        node: Any = data
        for depth, key in enumerate(keys[:-1]):
            child = node.get(key) if isinstance(node, dict) else None
            if child is None and isinstance(node, dict):
                child = node[key] = {}
            if not isinstance(child, dict):
                where = ".".join(keys[: depth + 1])
                problems.append(f"--set {quoted(override)}: {where} is not a mapping")
                break
            node = child
        else:
            node[keys[-1]] = value
    return problems


def _pydantic_problems(error: ValidationError, prefix: str, model: type[BaseModel]) -> list[str]:
    lines = []
    for item in error.errors():
        location = ".".join(str(part) for part in item["loc"])
        path = f"{prefix}.{location}" if location else prefix
        if item["type"] == "extra_forbidden":
            valid = list(model.model_fields)
            close = difflib.get_close_matches(str(item["loc"][-1]), valid, n=2, cutoff=0.5)
            hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
            lines.append(f"{path}: unknown parameter{hint} (valid: {', '.join(valid) or 'none'})")
            continue
        message = str(item["msg"])
        message = message.replace("Input should be", "expected").replace("Value error, ", "")
        if item["type"] == "missing":
            lines.append(f"{path}: required value is missing")
        else:
            lines.append(f"{path}: {message}, got {quoted(item.get('input'))}")
    return lines


def _unknown_key(path: str, key: Any, valid: Sequence[str]) -> str:
    shown = str(key) if isinstance(key, str | int) and len(str(key)) <= 60 else quoted(key, 60)
    close = difflib.get_close_matches(shown, valid, n=2, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    return f"{path}{'.' if path else ''}{shown}: unknown key{hint} (valid: {', '.join(valid)})"


def resolve_stage(
    registry: Registry, kind: str, spec: Any, path: str, problems: list[str]
) -> StageConfig | None:
    """Validate one ``{type, params}`` stage, its nested stages included (the one place).

    A nested stage (a gap matcher's ``predictor``) sits in its parent's ``params`` and is written
    like any stage: ``predictor: {type: ar, params: {orders: [1, 2]}}``; when it is left out the
    parent class's ``default_<name>`` type is used with default parameters.

    Args:
        registry: the plugin registry.
        kind: the stage kind.
        spec: the YAML value.
        path: its YAML path, for messages (``stages.gap_matcher``).
        problems: receives one line per problem.

    Returns:
        The validated configuration, or None when ``problems`` got a line.
    """
    if not isinstance(spec, Mapping):
        problems.append(
            f"{path}: expected a mapping with 'type' and optional 'params', got {quoted(spec)}"
        )
        return None
    unknown = [key for key in spec if key not in STAGE_KEYS]
    for key in unknown:
        line = _unknown_key(path, key, STAGE_KEYS)
        if kind in NESTED_KINDS:
            # Before issue 15 a nested stage's parameters sat beside its type.
            line += (
                f"; a {kind}'s parameters go under 'params' ({{type: ..., params: {{{key}: ...}}}})"
            )
        problems.append(line)
    cls = _stage_class(registry, kind, spec.get("type"), path, problems)
    params = spec.get("params") or {}
    if cls is None:
        return None
    if not isinstance(params, Mapping):
        problems.append(f"{path}.params: expected a mapping of parameters, got {quoted(params)}")
        return None
    params = dict(params)
    nested = _resolve_nested(registry, cls, params, path, problems)
    try:
        model = cls.Params(**params)
    except ValidationError as error:
        problems.extend(_pydantic_problems(error, f"{path}.params", cls.Params))
        return None
    except UserError as error:
        problems.extend(f"{path}.params: {line}" for line in error.lines)
        return None
    if unknown or nested is None:
        return None
    return StageConfig(kind, cls.name, cls, model, nested)


def _stage_class(
    registry: Registry, kind: str, type_name: Any, path: str, problems: list[str]
) -> type[Stage[Any]] | None:
    """The class registered as ``type_name`` for ``kind``, or None with a problem line."""
    if not isinstance(type_name, str) or not type_name:
        problems.append(
            f"{path}.type: expected the name of a {kind.replace('_', ' ')} plugin ({', '.join(registry.names(kind))})"
        )
        return None
    if (kind, type_name) not in registry.stages:
        problems.append(
            f"{path}.type: {unknown_name_message(kind, type_name, registry.names(kind))}"
        )
        return None
    return registry.stages[(kind, type_name)].cls


def _resolve_nested(
    registry: Registry,
    cls: type[Stage[Any]],
    params: dict[str, Any],
    path: str,
    problems: list[str],
) -> dict[str, StageConfig] | None:
    """Pop and resolve ``cls``'s nested stages from ``params``; None when one is invalid."""
    nested: dict[str, StageConfig] = {}
    for key, nested_kind in cls.nested.items():
        nested_spec = params.pop(key, None)
        if nested_spec is None:
            nested_spec = {"type": getattr(cls, f"default_{key}", None)}
        checked = resolve_stage(
            registry, nested_kind, nested_spec, f"{path}.params.{key}", problems
        )
        if checked is not None:
            nested[key] = checked
    return nested if len(nested) == len(cls.nested) else None


def _pipeline_kinds(
    stages_data: Mapping[str, Any], engine: EngineOptions, problems: list[str]
) -> tuple[str, ...]:
    """The kinds this pipeline must configure: a segment or a batch pipeline, never both.

    Problems with the combination (both trackers, neither, a classifier a batch pipeline would
    not use, ``infoless_frames: drop`` without a classifier) go to ``problems``, one line each.
    """
    segment = [kind for kind in ("tracker", "gap_matcher") if kind in stages_data]
    if "batch_tracker" not in stages_data:
        if not segment:
            problems.append(
                "stages: no tracker; expected either tracker + classifier + gap_matcher (a segment"
                " pipeline) or batch_tracker (a batch pipeline)"
            )
            return tuple(kind for kind in ("detector", "classifier") if kind in stages_data)
        if engine.infoless_frames == "drop":
            problems.append(
                "engine.infoless_frames: 'drop' applies to batch pipelines only; a segment"
                " pipeline skips info-less frames itself (expected 'keep' or no value)"
            )
        return STAGE_KINDS
    if segment:
        problems.append(
            f"stages: {' and '.join(segment)} given with batch_tracker; expected either a segment"
            " tracker (tracker + classifier + gap_matcher) or a batch tracker, not both"
        )
    if engine.infoless_frames == "drop":
        if "classifier" not in stages_data:
            problems.append(
                "engine.infoless_frames: 'drop' needs stages.classifier, which decides the"
                " info-less frames"
            )
        return (*BATCH_KINDS, "classifier")
    if "classifier" in stages_data and not segment:
        problems.append(
            "stages.classifier: a batch pipeline uses a classifier only with"
            " engine.infoless_frames: drop; remove it or set that option"
        )
    return BATCH_KINDS


def load_pipeline(
    path: str | Path,
    registry: Registry,
    overrides: Sequence[str] = (),
    build_check: bool = True,
) -> Pipeline:
    """Read, override and validate a pipeline file.

    Args:
        path: the YAML file.
        registry: the plugin registry.
        overrides: ``PATH=VALUE`` strings (``--set``).
        build_check: also construct every stage once, so that missing model files and other
            construction-time problems are reported now, not after frames were read.

    Raises:
        UserError: with one line per problem, each naming the file and the YAML path.
    """
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise UserError(f"{source}: pipeline file not found.")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise UserError(f"{source}: cannot read the pipeline ({error}).") from None
    data = parse_yaml(text, source)
    if data is None:
        raise UserError(f"{source}: empty pipeline; expected a mapping with 'name' and 'stages'.")
    if not isinstance(data, dict):
        raise UserError(
            f"{source}: expected a mapping with 'name' and 'stages' at the top level, got {type(data).__name__}."
        )
    return validate_pipeline(
        data, registry, source=source, overrides=overrides, build_check=build_check, path=path
    )


def _engine_options(data: Any, problems: list[str]) -> EngineOptions:
    """The ``engine:`` options (defaults where they are invalid, with a problem line)."""
    try:
        return EngineOptions(**(data or {}))
    except ValidationError as error:
        problems.extend(_pydantic_problems(error, "engine", EngineOptions))
    except TypeError:
        problems.append("engine: expected a mapping")
    return EngineOptions()


def _resolve_stages(
    registry: Registry, stages_data: Any, engine: EngineOptions, problems: list[str]
) -> dict[str, StageConfig]:
    """Kind -> validated stage for every kind the pipeline needs."""
    stages: dict[str, StageConfig] = {}
    if not isinstance(stages_data, Mapping):
        problems.append(
            f"stages: expected a mapping with {', '.join(STAGE_KINDS)} (a segment pipeline) or"
            f" {', '.join(BATCH_KINDS)} (a batch pipeline)"
        )
        return stages
    for kind in stages_data:
        if kind not in PIPELINE_KINDS:
            problems.append(_unknown_key("stages", kind, PIPELINE_KINDS))
    for kind in _pipeline_kinds(stages_data, engine, problems):
        if kind not in stages_data:
            problems.append(
                f"stages.{kind}: missing; expected {{type: ...}} ({', '.join(registry.names(kind))})"
            )
            continue
        checked = resolve_stage(registry, kind, stages_data[kind], f"stages.{kind}", problems)
        if checked is not None:
            stages[kind] = checked
    return stages


def validate_pipeline(
    data: dict[str, Any],
    registry: Registry,
    source: str = "<pipeline>",
    overrides: Sequence[str] = (),
    build_check: bool = True,
    path: Path | None = None,
) -> Pipeline:
    """Validate a pipeline given as plain data (see :func:`load_pipeline`)."""
    data = copy.deepcopy(data)
    problems = apply_overrides(data, overrides, source)
    for key in data:
        if key not in TOP_LEVEL_KEYS:
            problems.append(_unknown_key("", key, TOP_LEVEL_KEYS))
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        problems.append("name: expected a non-empty string naming the pipeline")
    description = data.get("description", "")
    if not isinstance(description, str):
        problems.append(f"description: expected a string, got {quoted(description)}")
    default_input = data.get("input")
    if default_input is not None and not isinstance(default_input, str):
        problems.append(f"input: expected a path or builtin:NAME, got {quoted(default_input)}")
    engine = _engine_options(data.get("engine"), problems)
    stages = _resolve_stages(registry, data.get("stages"), engine, problems)
    if problems:
        raise UserError(*(f"{source}: {line}" for line in problems))
    pipeline = Pipeline(
        name=str(name),
        description=str(description or ""),
        input=default_input,
        stages=stages,
        engine=engine,
        source=path,
    )
    if build_check:
        for kind, spec in stages.items():
            try:
                spec.build()
            except UserError as error:
                problems.extend(f"stages.{kind}: {line}" for line in error.lines)
        if problems:
            raise UserError(*(f"{source}: {line}" for line in problems))
    return pipeline
