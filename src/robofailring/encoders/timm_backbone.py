"""`timm:<model>[:<checkpoint>]`: a timm backbone's pooled features as the embedding (docs/encoders.md).

Robot-learning people have such backbones on disk (DINOv2, SigLIP towers, ResNets, EfficientNets): the
model is built by `timm.create_model(<model>, num_classes=0)` and its weights come from a checkpoint
file, else the local Hugging Face cache (never downloaded: the same error as open_clip's says how to
provide them). A checkpoint whose names differ from timm's but whose tensors match its parameters one
for one, in order and shape (EfficientNet-PyTorch's naming of the same network), is loaded by that
order; anything else is an error naming the first tensor that does not fit. Images are resized whole
to the model's square input (no centre crop: a robot camera's edges matter) and normalised with the
model's own mean and spread (timm's data config), in torch here and in its ONNX export alike. The
identity names the model and the digest of the checkpoint (or the pretrained tag of the cache).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.encoders.base import file_digest, l2_normalize
from robofailring.encoders.device import pick_device
from robofailring.encoders.openclip import _offline_unless_reachable
from robofailring.encoders.spec import EncoderSpec, Network
from robofailring.encoders.trained import normalizer, prepare_images, to_tensor
from robofailring.errors import EncoderError, WeightsUnavailableError
from robofailring.extras import needs_extra

_HOW_TO_PROVIDE = (
    "No weights can be downloaded on this machine. Provide them in one of two ways: (1) on a machine with "
    "internet, run `python -c \"import timm; timm.create_model('{model}', pretrained=True)\"` and copy the "
    "Hugging Face cache (~/.cache/huggingface) here, or set HF_HUB_CACHE to a folder that holds it; (2) pass a "
    "local checkpoint file: `timm:{model}:/path/to/checkpoint.pth` (a state_dict saved with torch.save)."
)


def timm_identity(model: str, checkpoint: str) -> str:
    """`timm:<model>:file-<digest>` for a checkpoint file, `timm:<model>:pretrained` for the cache's weights."""
    if not checkpoint:
        return f"timm:{model}:pretrained"
    path = Path(checkpoint).expanduser()
    if not path.is_file():
        raise EncoderError(f"timm checkpoint {path} does not exist")
    return f"timm:{model}:file-{file_digest(path)}"


def _state_dict(path: Path) -> dict[str, Any]:
    with needs_extra("clip"):
        import torch

    try:
        loaded = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # torch raises many types for a file that is not a checkpoint
        raise EncoderError(f"cannot read timm checkpoint {path}: {type(error).__name__}: {error}") from error
    for key in ("state_dict", "model"):
        if isinstance(loaded, dict) and isinstance(loaded.get(key), dict):
            loaded = loaded[key]
    if not isinstance(loaded, dict):
        raise EncoderError(f"timm checkpoint {path} holds no state_dict")
    return dict(loaded)


def load_weights(model: Any, path: Path) -> None:
    """`path`'s tensors into `model`: by name where the names are timm's, else by order when every tensor
    matches a parameter or buffer in order and shape (the classifier left out); else an EncoderError."""
    state = {k: v for k, v in _state_dict(path).items() if hasattr(v, "shape")}
    own = {k: v for k, v in model.state_dict().items() if not k.endswith("num_batches_tracked")}
    if set(state) >= set(own):
        model.load_state_dict({k: state[k] for k in own}, strict=False)
        return
    given = [  # batch-norm step counters (whole-number scalars) are no weights, whatever their names
        (k, v)
        for k, v in state.items()
        if not k.endswith("num_batches_tracked") and not (v.ndim == 0 and not v.is_floating_point())
    ]
    names = list(own)
    if len(given) < len(names):
        raise EncoderError(f"timm checkpoint {path} has {len(given)} tensors; the model needs {len(names)}")
    for (name, target), (key, tensor) in zip(own.items(), given, strict=False):
        if tuple(target.shape) != tuple(tensor.shape):
            raise EncoderError(
                f"timm checkpoint {path}: tensor {key!r} {tuple(tensor.shape)} does not fit the model's {name!r} "
                f"{tuple(target.shape)} (names differ, so tensors are matched in order)"
            )
    model.load_state_dict(
        {name: tensor for name, (_, tensor) in zip(names, given, strict=False)}, strict=False
    )


class TimmEncoder:
    """A timm backbone's pooled, L2-normalised features (see the module docstring)."""

    def __init__(
        self, model: str, checkpoint: str = "", *, device: str | None = None, batch_size: int = 64
    ) -> None:
        with needs_extra("clip"):
            import timm
            import torch

        self._identity = timm_identity(model, checkpoint)
        self._device = pick_device(device)
        self._batch_size = batch_size
        try:
            with _offline_unless_reachable():
                network = timm.create_model(model, pretrained=not checkpoint, num_classes=0)
        except RuntimeError as error:  # timm's unknown model
            raise EncoderError(f"unknown timm model {model!r}: {error}") from error
        except Exception as error:  # no weights in the cache, or the hub cannot be reached
            raise WeightsUnavailableError(
                f"weights for timm:{model} are not available here ({type(error).__name__}). "
                + _HOW_TO_PROVIDE.format(model=model)
            ) from error
        if checkpoint:
            load_weights(network, Path(checkpoint).expanduser())
        config = timm.data.resolve_data_config({}, model=network)
        self.side = int(config["input_size"][-1])
        self.mean = [float(v) for v in config["mean"]]
        self.std = [float(v) for v in config["std"]]
        self.network = network.eval().to(self._device)
        self._dim = int(getattr(network, "num_features"))  # noqa: B009  (timm types it as a module attribute)
        self._torch = torch

    @property
    def identity(self) -> str:
        return self._identity

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def preprocessing(self) -> dict[str, Any]:
        """What an ONNX export records to prepare pixels as this encoder does."""
        return {"kind": "square", "size": self.side, "mean": self.mean, "std": self.std}

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            return np.zeros((0, self._dim), dtype=np.float32)
        mean, std = normalizer({"normalize": {"mean": self.mean, "std": self.std}}, self._device)
        outputs = []
        with self._torch.inference_mode():
            for start in range(0, len(images), self._batch_size):
                batch = prepare_images(images[start : start + self._batch_size], self.side)
                pixels = (to_tensor(batch, self._device) - mean) / std
                outputs.append(self.network(pixels).float().cpu().numpy())
        return l2_normalize(np.concatenate(outputs))


def load(spec: EncoderSpec, device: str | None) -> TimmEncoder:
    """The kind's encoder (`spec.py`)."""
    return TimmEncoder(spec.model, spec.weights, device=device)


def export_identity(spec: EncoderSpec) -> tuple[str, str]:
    identity = timm_identity(spec.model, spec.weights)
    return identity, identity


def network(spec: EncoderSpec) -> Network:
    backbone = TimmEncoder(spec.model, spec.weights, device="cpu")
    return Network(backbone.network, backbone.side, backbone.preprocessing, backbone.identity, backbone.dim)
