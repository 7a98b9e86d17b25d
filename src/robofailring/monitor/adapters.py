"""Observations of the rollout loops people run, read as the detector's views and the robot's signals.

One small class per convention (docs/rollouts.md, "Adapters"): `LeRobotAdapter` (`observation.images.<cam>`,
`observation.image`, `observation.state`, LeRobot's raw `pixels`/`agent_pos`), `ManiSkillAdapter`
(`sensor_data/<cam>/rgb`, `agent/*`, `extra/*`, batched torch tensors), `RobosuiteAdapter` (robosuite, LIBERO and
robomimic: `<camera>_image`, `robot0_*`) and `MappingAdapter` (the keys a user names). Each names its views and
signals as the project's loader of that layout does, so a memory built from such a dataset meets the same names
live. No gymnasium and no torch here: tensors are read through their own `numpy()`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final, Protocol

import numpy as np

from robofailring.data.images import as_rgb
from robofailring.data.model import Outcome
from robofailring.data.signals import SignalKind, kind_of
from robofailring.errors import RolloutError, SettingError

#: The keys of an env's `info` that carry its own verdict on the episode, in the order they are asked.
SUCCESS_KEYS: Final[tuple[str, ...]] = ("is_success", "success")


def as_array(value: Any) -> np.ndarray:
    """A numpy array of an observation's value: a torch tensor (on any device), a list or an array."""
    if hasattr(value, "detach"):  # torch, without importing it
        value = value.detach().cpu().numpy()
    return np.asarray(value)


def lookup(observation: Any, key: str) -> Any:
    """The value at `key`: the key itself (LeRobot's dotted names), else a `/` path through nested mappings."""
    if isinstance(observation, Mapping) and key in observation:
        return observation[key]
    value = observation
    for part in key.split("/"):
        if not isinstance(value, Mapping) or part not in value:
            return None
        value = value[part]
    return value


def keys_of(observation: Any, prefix: str = "") -> list[str]:
    """Every leaf key of a (nested) observation as a `/` path, for error messages."""
    if not isinstance(observation, Mapping):
        return [prefix or "(the observation itself)"]
    found: list[str] = []
    for key, value in observation.items():
        path = f"{prefix}/{key}" if prefix else str(key)
        found.extend(keys_of(value, path) if isinstance(value, Mapping) else [path])
    return found


def _unbatched(array: np.ndarray, where: str, ndim: int) -> np.ndarray:
    """An array without the leading batch axis of one env (ManiSkill3, LeRobot's processed observations)."""
    if array.ndim == ndim + 1:
        if array.shape[0] != 1:
            raise RolloutError(
                f"{where}: a batch of {array.shape[0]} envs in one observation; wrap a batched env as a vector "
                "env (gymnasium's, or ManiSkill's ManiSkillVectorEnv) and use VectorRolloutMonitor"
            )
        return array[0]
    return array


def as_image(value: Any, where: str, *, flip: bool = False) -> np.ndarray:
    """An (H, W, 3) uint8 image from HWC or CHW, uint8 or float in [0, 1], with or without a batch of one."""
    array = _unbatched(as_array(value), where, 3)
    if array.ndim == 3 and array.shape[0] in (1, 3, 4) and array.shape[-1] not in (1, 3, 4):
        array = np.moveaxis(array, 0, -1)  # CHW (LeRobot's processed frames)
    if array.ndim == 3 and array.shape[-1] == 1:
        array = array[:, :, 0]
    image = as_rgb(array, source=where)
    return np.ascontiguousarray(image[::-1]) if flip else image


def as_vector(value: Any, where: str) -> np.ndarray:
    """A signal's values at one step as (D,) float64 (NaN kept: the caller names it)."""
    array = as_array(value)
    if array.dtype.kind not in "biuf":
        raise RolloutError(f"{where}: values of type {array.dtype} are not numbers")
    if array.ndim == 2:
        array = _unbatched(array, where, 1)
    return array.astype(np.float64).reshape(-1)


def outcome_of(info: Mapping[str, Any]) -> Outcome | None:
    """The env's own verdict in `info` (`is_success`, `success`, or in `final_info`), None where it gives none."""
    for key in SUCCESS_KEYS:
        if key in info:
            value = as_array(info[key]).reshape(-1)
            if value.size == 1 and value.dtype.kind in "biuf":
                return Outcome.SUCCESS if bool(value[0]) else Outcome.FAILURE
    final = info.get("final_info")
    return outcome_of(final) if isinstance(final, Mapping) else None


@dataclass(frozen=True)
class Observed:
    """One step's observation read: the image per view and the robot's signals ({name: (D,) values})."""

    views: dict[str, np.ndarray]
    signals: dict[str, np.ndarray]


class Adapter(Protocol):
    """Reads one env's observations (and the action passed to `step`) as views and signals."""

    @property
    def name(self) -> str: ...

    def observe(self, observation: Any, *, step: int) -> Observed: ...

    def action_signals(self, action: Any, *, step: int) -> dict[str, np.ndarray]: ...

    def kind(self, signal: str) -> SignalKind: ...


@dataclass(frozen=True)
class KeyAdapter:
    """What every convention shares: cameras and state found by key, the action under one signal name."""

    name: str = "keys"
    action: str | None = "action"  # the signal name of the action passed to `step` (None: not recorded)
    flip: bool = False  # images stored bottom row first (robosuite's OpenGL convention): turned upright

    def cameras(self, observation: Any) -> dict[str, str]:
        """{view: key} of the observation's camera images."""
        raise NotImplementedError

    def states(self, observation: Any) -> dict[str, str]:
        """{signal name: key} of the robot's state in the observation."""
        raise NotImplementedError

    def observe(self, observation: Any, *, step: int) -> Observed:
        cameras = self.cameras(observation)
        if not cameras:
            raise RolloutError(
                f"step {step}: the observation has no camera the {self.name} adapter maps (its keys: "
                f"{', '.join(keys_of(observation)[:12])}); pass adapter=MappingAdapter(views={{...}})"
            )
        views = {
            view: as_image(lookup(observation, key), f"step {step}: observation {key!r}", flip=self.flip)
            for view, key in cameras.items()
        }
        signals = {
            name: as_vector(value, f"step {step}: observation {key!r}")
            for name, key in self.states(observation).items()
            if (value := lookup(observation, key)) is not None
        }
        return Observed(views, signals)

    def action_signals(self, action: Any, *, step: int) -> dict[str, np.ndarray]:
        if self.action is None or action is None:
            return {}
        array = as_array(action)
        if array.dtype.kind not in "biuf":
            return {}  # a dict or text action: not a signal
        return {self.action: as_vector(array, f"step {step}: the action")}

    def kind(self, signal: str) -> SignalKind:
        return SignalKind.ACTION if signal == self.action else kind_of(signal)


_LEROBOT_IMAGES: Final[str] = "observation.images."


@dataclass(frozen=True)
class LeRobotAdapter(KeyAdapter):
    """LeRobot: `observation.images.<cam>` (view `<cam>`), `observation.image` (view `image`) and
    `observation.state`, or a LeRobot gym env's raw `pixels`/`pixels/<cam>` and `agent_pos`; the action `action`."""

    name: str = "lerobot"

    def cameras(self, observation: Any) -> dict[str, str]:
        keys = list(observation) if isinstance(observation, Mapping) else []
        found = {key.removeprefix(_LEROBOT_IMAGES): key for key in keys if key.startswith(_LEROBOT_IMAGES)}
        if "observation.image" in keys:
            found["image"] = "observation.image"
        pixels = observation.get("pixels") if isinstance(observation, Mapping) else None
        if isinstance(pixels, Mapping):
            found |= {str(cam): f"pixels/{cam}" for cam in pixels}
        elif pixels is not None:
            found["image"] = "pixels"
        return found

    def states(self, observation: Any) -> dict[str, str]:
        key = "observation.state" if lookup(observation, "observation.state") is not None else "agent_pos"
        return {"observation.state": key}


@dataclass(frozen=True)
class ManiSkillAdapter(KeyAdapter):
    """ManiSkill3 (`obs_mode="rgb"`): `sensor_data/<cam>/rgb` (view `<cam>`), `agent/*` and `extra/*` signals as
    its trajectories name them (`agent/qpos`), the action `actions`; torch tensors with a batch of one env."""

    name: str = "maniskill"
    action: str | None = "actions"

    def cameras(self, observation: Any) -> dict[str, str]:
        sensors = lookup(observation, "sensor_data")
        if not isinstance(sensors, Mapping):
            return {}
        return {
            str(cam): f"sensor_data/{cam}/rgb"
            for cam, data in sensors.items()
            if isinstance(data, Mapping) and "rgb" in data
        }

    def states(self, observation: Any) -> dict[str, str]:
        found = {}
        for part in ("agent", "extra"):
            group = lookup(observation, part)
            for key, value in group.items() if isinstance(group, Mapping) else ():
                if not isinstance(value, Mapping) and as_array(value).dtype.kind in "biuf":
                    found[f"{part}/{key}"] = f"{part}/{key}"
        return found


@dataclass(frozen=True)
class RobosuiteAdapter(KeyAdapter):
    """robosuite, LIBERO and robomimic: `<camera>_image` (view `<camera>`: `agentview`, `robot0_eye_in_hand`),
    the low-dim observations as robomimic's files name them (`obs/robot0_eef_pos`, `obs/robot0_gripper_qpos`),
    the action `actions`; images turned upright (robosuite renders bottom row first)."""

    name: str = "robosuite"
    action: str | None = "actions"
    flip: bool = True

    def cameras(self, observation: Any) -> dict[str, str]:
        keys = list(observation) if isinstance(observation, Mapping) else []
        return {key.removesuffix("_image"): key for key in keys if key.endswith("_image")}

    def states(self, observation: Any) -> dict[str, str]:
        keys = list(observation) if isinstance(observation, Mapping) else []
        return {
            f"obs/{key}": key
            for key in keys
            if key.startswith("robot0_")
            and not key.endswith("_image")
            and as_array(observation[key]).ndim <= 1
        }


@dataclass(frozen=True)
class MappingAdapter(KeyAdapter):
    """The keys a user names: `views` {view: key}, `signals` {signal name: key}, keys as `/` paths."""

    name: str = "mapping"
    views: Mapping[str, str] = field(default_factory=dict)
    signals: Mapping[str, str] = field(default_factory=dict)

    def observe(self, observation: Any, *, step: int) -> Observed:
        missing = [key for key in self.views.values() if lookup(observation, key) is None]
        if missing:
            raise RolloutError(
                f"step {step}: the observation has no {missing[0]!r} (a mapped view); its keys: "
                f"{', '.join(keys_of(observation)[:12])}"
            )
        return super().observe(observation, step=step)

    def cameras(self, observation: Any) -> dict[str, str]:
        return dict(self.views)

    def states(self, observation: Any) -> dict[str, str]:
        return dict(self.signals)


ADAPTERS: Final[dict[str, type[KeyAdapter]]] = {
    "lerobot": LeRobotAdapter,
    "maniskill": ManiSkillAdapter,
    "robosuite": RobosuiteAdapter,
}


def adapter_for(observation: Any) -> KeyAdapter:
    """The adapter whose convention the observation follows (its keys), or a RolloutError listing them."""
    for adapter in (ManiSkillAdapter(), LeRobotAdapter(), RobosuiteAdapter()):
        if adapter.cameras(observation):
            return adapter
    raise RolloutError(
        f"the observation follows none of the conventions the monitor knows (LeRobot, ManiSkill3, robosuite); "
        f"its keys: {', '.join(keys_of(observation)[:12])}; pass adapter=MappingAdapter(views={{...}})"
    )


def named_adapter(adapter: str | Adapter | None) -> Adapter | None:
    """`adapter` as given, by its name (`lerobot`, `maniskill`, `robosuite`), or None: chosen at the first reset."""
    if adapter is None or adapter == "auto":
        return None
    if isinstance(adapter, str):
        if adapter not in ADAPTERS:
            raise SettingError(
                f"unknown adapter {adapter!r}; expected auto, {', '.join(ADAPTERS)} or an Adapter"
            )
        return ADAPTERS[adapter]()
    return adapter
