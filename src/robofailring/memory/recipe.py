"""`MemoryRecipe`: how a memory is made, as one value, with its defaults in this one place.

A recipe names the encoder, which failure frames become entries (`dense` or the paper's `end`), how a
first and a current frame are paired (`change` or the paper's `concat`), how finely success runs
(and a dense memory's failure runs) are thinned, and which of the robot's signals are a second modality
(`auto`: every state and action signal the data has; `none`; or names) and which features are derived
from them (`change`, `events`; `none`). A built memory carries its own (`FailureMemory.recipe`,
read from its manifest) and pairs its queries by it; jobs that build memories take one recipe. A recipe made by
`MemoryRecipe.chosen` also knows which settings were chosen: a memory grown (`build-memory --add-to`) keeps
its own for the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from robofailring.errors import SettingError
from robofailring.memory.entry import DENSE, END, check_failure_frames
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.pairs import CHANGE, CONCAT, check_pairing
from robofailring.memory.signals.derived import DEFAULT_FEATURES, NO_FEATURES, SignalFeatures
from robofailring.memory.signals.layout import AUTO as SIGNALS_AUTO
from robofailring.memory.signals.layout import NONE as SIGNALS_NONE
from robofailring.memory.signals.layout import check_choice
from robofailring.memory.signals.memory import DEFAULT_START_WEIGHT
from robofailring.memory.signals.task import check_start_weight
from robofailring.memory.thinning import DEFAULT_STEP, check_step

DEFAULT_ENCODER: Final[str] = "pixels"  # weight-free: what a memory is built with when no encoder is named


@dataclass(frozen=True)
class MemoryRecipe:
    """How a memory is made; the defaults are the benchmark's best (docs/memory.md, "Pairing")."""

    encoder: str = DEFAULT_ENCODER  # encoder spec: `pixels`, `open_clip:…` or `trained:DIR`
    failure_frames: str = DENSE  # `dense`: a failure run's frames from its onset on; `end`: the paper's
    pairing: str = CHANGE  # `change`: norm([½ z_0 ‖ z_t − z_0]); `concat`: the paper's norm([z_0 ‖ z_t])
    success_step: float = (
        DEFAULT_STEP  # thinning (cosine) of success runs and dense failure runs; 0 keeps all
    )
    signals: str = SIGNALS_AUTO  # the robot's signals used beside the cameras: `auto`, `none` or names
    # features derived from them (robofailring.memory.signals.derived): `change`, `events`, both, or `none`; given
    # as text (`--signal-features`), parsed here once
    signal_features: SignalFeatures = DEFAULT_FEATURES
    # the start state's weight in the signal vectors (robofailring.memory.signals.memory): ½, or 0 to leave it out
    signal_start_weight: float = DEFAULT_START_WEIGHT
    # the settings chosen, by field name (`MemoryRecipe.chosen`); None: all of them (a recipe written out)
    given: frozenset[str] | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:  # a bad setting fails before any frame is read
        if not isinstance(self.encoder, str) or not self.encoder:
            raise SettingError(f"a memory's encoder must be an encoder spec, got {self.encoder!r}")
        try:
            check_choice(self.signals)
            if not isinstance(self.signal_features, SignalFeatures):  # text, as a user or option gives it
                object.__setattr__(self, "signal_features", SignalFeatures.parse(self.signal_features))
        except ValueError as error:
            raise SettingError(str(error)) from error
        try:
            check_start_weight(self.signal_start_weight)
        except ValueError as error:
            raise SettingError(str(error)) from error
        check_failure_frames(self.failure_frames)
        check_pairing(self.pairing)
        check_step(self.success_step)

    @classmethod
    def paper(cls, encoder: str = DEFAULT_ENCODER) -> MemoryRecipe:
        """The paper's memory (Algorithm 1): one end entry per failure view, frames paired by `concat`."""
        return cls(encoder=encoder, failure_frames=END, pairing=CONCAT)

    @classmethod
    def chosen(
        cls,
        encoder: str = DEFAULT_ENCODER,
        *,
        failure_frames: str | None = None,
        pairing: str | None = None,
        success_step: float | None = None,
        signals: str | None = None,
        signal_features: str | None = None,
        signal_start_weight: float | None = None,
    ) -> MemoryRecipe:
        """The recipe of the settings given, the defaults for those left out (None): what options build. It
        remembers which were given (`was_given`); the encoder always is."""
        default = cls(encoder=encoder)
        settings = {
            "failure_frames": failure_frames,
            "pairing": pairing,
            "success_step": success_step,
            "signals": signals,
            "signal_features": signal_features,
            "signal_start_weight": signal_start_weight,
        }
        return cls(
            encoder=encoder,
            failure_frames=failure_frames if failure_frames is not None else default.failure_frames,
            pairing=pairing if pairing is not None else default.pairing,
            success_step=success_step if success_step is not None else default.success_step,
            signals=signals if signals is not None else default.signals,
            signal_features=_features(signal_features)
            if signal_features is not None
            else default.signal_features,
            signal_start_weight=(
                signal_start_weight if signal_start_weight is not None else default.signal_start_weight
            ),
            given=frozenset({"encoder", *(name for name, value in settings.items() if value is not None)}),
        )

    def was_given(self, name: str) -> bool:
        """Whether the setting `name` (a field) was chosen, not left at its default."""
        return self.given is None or name in self.given

    @classmethod
    def of(cls, manifest: MemoryManifest) -> MemoryRecipe:
        """The recipe a memory was built with, from its manifest (one built before a setting existed: the
        paper's `end` frames and `concat` pairing; one without a signal memory, or from before derived
        signal features: `none`)."""
        return cls(
            encoder=manifest.encoder_spec or manifest.encoder,
            failure_frames=manifest.failure_mode,
            pairing=manifest.pairing_mode,
            success_step=manifest.failure_step if manifest.failure_step is not None else DEFAULT_STEP,
            signals=manifest.signals.choice if manifest.signals else SIGNALS_NONE,
            signal_features=manifest.signals.features if manifest.signals else NO_FEATURES,
            signal_start_weight=manifest.signals.start_weight if manifest.signals else DEFAULT_START_WEIGHT,
        )


def _features(text: str) -> SignalFeatures:
    """`--signal-features` parsed; SettingError naming the choices otherwise."""
    try:
        return SignalFeatures.parse(text)
    except ValueError as error:
        raise SettingError(str(error)) from error


DEFAULT_RECIPE: Final[MemoryRecipe] = MemoryRecipe()  # what a memory is built with when nothing is chosen
