"""Online decision rules of the info-less SVM [OURS; the paper leaves them open].

See docs/algorithms/infoless-classifier.md#online-rules.

The paper labels frame ``t`` info-less when the SVM says so, and the reference frame ``a`` of
``C_t`` is the most recent informative frame. Replayed online, this recursion has two weak
points: one wrong "info-less" call freezes ``a``, so ``C_t`` keeps comparing with an old scene
and the classifier can stay stuck; and a single informative call inside an interval moves ``a``
into the interval, after which ``C_t`` no longer sees the change. Two documented rules, both off
by default in :class:`OnlineRules` (paper behaviour) and set by the shipped model, address them:

* **Hysteresis** on the Platt probability: enter an interval when ``p >= enter_probability``,
  stay in it while ``p >= leave_probability`` (a lower value keeps a started interval open
  through frames the SVM finds only moderately info-less).
* **Re-anchoring**: after ``reanchor_after`` consecutive info-less decisions whose last
  ``HISTORY`` motion values ``M`` are all at most ``reanchor_max_motion`` (the camera is steady
  again) and whose last ``HISTORY`` detection counts ``N`` are all at least
  ``reanchor_min_detections`` (people are in view, so ``S_t > 0``; a reference with ``S_a = 0``
  would pin ``C_t`` at ``C_max``), the current frame becomes the reference of ``C_t`` although it
  stays info-less. If the scene is the old one seen anew, ``C_t`` drops and the classifier can
  leave the interval.

* **Turn latch**: an interval that starts during a camera turn (``M_t >= turn_motion`` on its
  first frame, or on its first turn with ``latch_late_turns``) is kept open, whatever the probability, until a
  second turn (the way back) has ended, or for at most ``max_hold`` frames. While the latch
  holds, re-anchoring waits; when it lets go on a frame still called info-less that shows
  people, that frame becomes the reference (``reanchor_on_release``): the camera is back, so
  ``C_t`` should compare with the scene it came back to, not with the one before the turn. This is meant for "another group" intervals: once the camera
  rests on the other group, ``M`` is low and ``N`` steady, and the SVM's probability falls as
  soon as ``C_t`` is small, after which the reference would move into the interval.
* **No people, no way out**: an interval is not left on a frame with fewer than
  ``leave_min_detections`` detections. A camera resting on the sky has a low ``M`` and no
  people, and the SVM's probability can fall below the leave threshold there; the frame would
  become the reference of ``C_t`` with ``S_a = 0``, which pins ``C_t`` at ``C_max`` on every
  frame after the camera is back, and the video stays info-less to its end.

All depend only on the past, so the stage stays strictly online.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from trackfw.arrays import FloatArray
from trackfw.errors import UserError
from trackfw_plugins.classifiers.infoless_features import (
    HISTORY,
    FeatureAssembler,
    latest_count,
    latest_motion,
)


@dataclass(frozen=True)
class OnlineRules:
    """Settings of the online rules; the defaults are the paper's plain 0.5 decision.

    Attributes:
        enter_probability: probability at which an informative state turns info-less.
        leave_probability: an info-less state stays info-less while the probability is at
            least this (``<= enter_probability``).
        reanchor_after: consecutive info-less decisions before the reference of ``C_t`` is
            moved to the current frame; 0 disables re-anchoring.
        reanchor_max_motion: re-anchor only when every ``M`` in the feature's history is at
            most this (working-resolution pixels); ``inf`` for no motion condition.
        reanchor_min_detections: re-anchor only when every ``N`` in the feature's history is
            at least this.
        turn_motion: ``M`` (working-resolution pixels) from which a frame counts as part of a
            camera turn; ``inf`` disables the turn latch.
        max_hold: the most frames the turn latch keeps one interval open.
        reanchor_on_release: when the latch lets go (the second turn has ended) and the frame
            is still info-less with at least ``reanchor_min_detections`` people, it becomes
            the reference of ``C_t``.
        latch_late_turns: an interval that began without a turn latches on its first turn.
        leave_min_detections: an info-less state stays info-less on a frame with fewer
            detections than this (0: the probability alone decides).
    """

    enter_probability: float = 0.5
    leave_probability: float = 0.5
    reanchor_after: int = 0
    reanchor_max_motion: float = math.inf
    reanchor_min_detections: int = 2
    turn_motion: float = math.inf
    max_hold: int = 300
    reanchor_on_release: bool = True
    latch_late_turns: bool = True
    leave_min_detections: int = 0

    def __post_init__(self) -> None:
        if not 0.0 <= self.leave_probability <= self.enter_probability <= 1.0:
            raise ValueError(
                "expected 0 <= leave_probability <= enter_probability <= 1, got"
                f" {self.leave_probability} and {self.enter_probability}"
            )
        if self.reanchor_after < 0:
            raise ValueError(f"reanchor_after must be >= 0, got {self.reanchor_after}")
        if self.max_hold < 0 or not self.turn_motion > 0:
            raise ValueError(
                f"expected max_hold >= 0 and turn_motion > 0, got {self.max_hold} and"
                f" {self.turn_motion}"
            )
        for name in ("reanchor_min_detections", "leave_min_detections"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not self.reanchor_max_motion >= 0:
            raise ValueError(f"reanchor_max_motion must be >= 0, got {self.reanchor_max_motion}")

    def as_dict(self) -> dict[str, Any]:
        """JSON form (``inf`` written as None), as recorded in a model file."""
        data = asdict(self)
        for key in ("reanchor_max_motion", "turn_motion"):
            if math.isinf(data[key]):
                data[key] = None
        return data

    @classmethod
    def from_dict(cls, data: Any, source: str = "model") -> OnlineRules:
        """Read :meth:`as_dict`'s form; a bad value is a :class:`UserError` naming ``source``."""
        if data is None:
            return cls()
        if not isinstance(data, dict) or set(data) - set(cls.__dataclass_fields__):
            raise UserError(
                f"{source}: online_rules is {data!r}; expected an object with keys among"
                f" {sorted(cls.__dataclass_fields__)}."
            )
        values = dict(data)
        for key in ("reanchor_max_motion", "turn_motion"):
            if key in values and values[key] is None:
                values[key] = math.inf
        try:
            return cls(
                enter_probability=float(values.get("enter_probability", 0.5)),
                leave_probability=float(values.get("leave_probability", 0.5)),
                reanchor_after=int(values.get("reanchor_after", 0)),
                reanchor_max_motion=float(values.get("reanchor_max_motion", math.inf)),
                reanchor_min_detections=int(values.get("reanchor_min_detections", 2)),
                turn_motion=float(values.get("turn_motion", math.inf)),
                max_hold=int(values.get("max_hold", 300)),
                reanchor_on_release=bool(values.get("reanchor_on_release", True)),
                latch_late_turns=bool(values.get("latch_late_turns", True)),
                leave_min_detections=int(values.get("leave_min_detections", 0)),
            )
        except (TypeError, ValueError) as error:
            raise UserError(f"{source}: online_rules: {error}.") from None


class OnlineDecider:
    """Applies :class:`OnlineRules` frame by frame to one :class:`FeatureAssembler`.

    Per frame: :meth:`decide` with the SVM's probability and the frame's feature, then
    :meth:`settle` with the final decision (the engine's, which may differ).

    Args:
        rules: the rule settings.
        assembler: the feature recursion whose reference the rules move.
    """

    def __init__(self, rules: OnlineRules, assembler: FeatureAssembler) -> None:
        self.rules = rules
        self.assembler = assembler
        self.reset()

    def reset(self) -> None:
        """Start a new video."""
        self.inside = False
        self.run = 0
        self._settled_t: int | None = None
        self._run_before = 0
        self._inside_before = False
        # Turn latch: whether the interval began with a turn, whether a turn is under way, how
        # many turns have ended since, and how many frames the interval has lasted.
        self._entry_turn = False
        self._in_turn = False
        self._turns_ended = 0
        self._held = 0
        self._released = False

    @property
    def holding(self) -> bool:
        """Whether the turn latch keeps the current interval open whatever the probability."""
        return (
            self.inside
            and self._entry_turn
            and self._turns_ended < 2
            and self._held < self.rules.max_hold
        )

    def decide(self, probability: float, features: FloatArray | None = None) -> bool:
        """The provisional decision for the latest frame: info-less or not.

        Args:
            probability: the SVM's Platt probability for the frame.
            features: the frame's ``(11,)`` feature; the turn latch needs its ``M_t``.
        """
        self._released = False
        if self.inside and features is not None and math.isfinite(self.rules.turn_motion):
            was_holding = self.holding
            turning = latest_motion(features) >= self.rules.turn_motion
            if turning and not self._entry_turn and self.rules.latch_late_turns:
                # An interval entered without a turn (the SVM was early) latches on its first.
                self._entry_turn, self._turns_ended, self._held = True, 0, 0
            elif self._in_turn and not turning:
                self._turns_ended += 1
            self._in_turn = turning
            self._held += 1
            self._released = was_holding and self._turns_ended >= 2
        if self.holding:
            return True
        if (
            self.inside
            and features is not None
            and latest_count(features) < self.rules.leave_min_detections
        ):
            return True
        limit = self.rules.leave_probability if self.inside else self.rules.enter_probability
        return probability >= limit

    def settle(self, t: int, infoless: bool, features: FloatArray) -> bool:
        """Record frame ``t``'s final decision; return True when ``t`` became the reference.

        May be called again for the same frame (a provisional decision, then the engine's
        final one): the second call replaces the first.

        Args:
            t: the latest pushed frame.
            infoless: its final decision.
            features: its ``(11,)`` feature ``[M_t-4..M_t, N_t-4..N_t, C_t]``.
        """
        self.assembler.mark_informative(t, not infoless)
        if t != self._settled_t:
            self._settled_t, self._run_before = t, self.run
            self._inside_before = self.inside
        self.inside = infoless
        self.run = self._run_before + 1 if infoless else 0
        if infoless and not self._inside_before:
            # A new interval latches only when it starts during a turn: a turn already over
            # may be the way back of the interval just left.
            self._entry_turn = latest_motion(features) >= self.rules.turn_motion
            self._in_turn = self._entry_turn
            self._turns_ended = 0
            self._held = 0
        if (
            infoless
            and self._released
            and self.rules.reanchor_on_release
            and latest_count(features) >= self.rules.reanchor_min_detections
        ):
            # The way back has ended: compare the next frames with the scene we came back to.
            self.assembler.reanchor(t)
            self.run = 0
            return True
        after = self.rules.reanchor_after
        if not infoless or after == 0 or self.run < after or self.holding:
            return False
        if max(float(value) for value in features[:HISTORY]) > self.rules.reanchor_max_motion:
            return False
        counts = features[HISTORY : 2 * HISTORY]
        if min(float(value) for value in counts) < self.rules.reanchor_min_detections:
            return False
        self.assembler.reanchor(t)
        self.run = 0
        return True


def model_rules(model: Any, source: str = "model") -> OnlineRules:
    """The rules a model file records under ``features.online_rules`` (paper rules if none)."""
    return OnlineRules.from_dict(model.features.get("online_rules"), source)
