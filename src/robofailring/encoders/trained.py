"""`trained:<DIR>`: an encoder trained on the user's own runs by `robofailring train-encoder`.

The folder holds `encoder.json` (architecture, input size, normalisation, the label classes and
how it was trained) and `weights.pt` (a torch state dict). Two architectures exist:

- `cnn`: a small 4-layer convolutional network on `input_size`² RGB frames; the embedding is its
  globally average-pooled last feature map, centred and scaled by a batch-norm neck.
- `open_clip_head`: a frozen open_clip image tower (`open_clip:<model>:<weights>`, loaded by the
  project's own open_clip loader) followed by a trained linear projection; `weights.pt` holds
  only the projection and the classifier.

The identity names the architecture, the input size and the digest of the weights, of the
normalisation and of the frozen tower's identity, so the embedding cache and the memory's encoder check treat a retrained encoder as a
different one, exactly as for CLIP checkpoints.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

import cv2
import numpy as np

from robofailring.encoders.base import file_digest, l2_normalize
from robofailring.encoders.spec import OPEN_CLIP, EncoderSpec, Network
from robofailring.encoders.trained_config import check_trained_config
from robofailring.errors import EncoderError
from robofailring.extras import needs_extra
from robofailring.jsontext import parse_json

CONFIG_NAME: Final[str] = "encoder.json"
WEIGHTS_NAME: Final[str] = "weights.pt"
FORMAT: Final[str] = "robofailring-trained-encoder"
FORMAT_VERSION: Final[int] = 1
CNN_WIDTHS: Final[tuple[int, ...]] = (32, 64, 128, 256)
CNN_MEAN: Final[tuple[float, float, float]] = (0.5, 0.5, 0.5)
CNN_STD: Final[tuple[float, float, float]] = (0.25, 0.25, 0.25)


def prepare_images(images: Sequence[np.ndarray], size: int) -> np.ndarray:
    """(N, size, size, 3) uint8: each RGB image resized to the encoder's square input (area filter when shrinking)."""
    prepared = np.empty((len(images), size, size, 3), dtype=np.uint8)
    for i, image in enumerate(images):
        if image.shape[0] == size and image.shape[1] == size:
            prepared[i] = image
            continue
        shrink = image.shape[0] > size or image.shape[1] > size
        prepared[i] = cv2.resize(
            image, (size, size), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR
        )
    return prepared


def build_network(architecture: dict[str, Any], classes: int, backbone: Any = None) -> Any:
    """The torch module of an architecture description (see the module docstring).

    `backbone` is the open_clip model for `open_clip_head` (frozen, not part of the state dict).
    """
    with needs_extra("clip"):
        import torch
        from torch import nn

    class SmallCNN(nn.Module):
        def __init__(self, widths: Sequence[int]) -> None:
            super().__init__()
            layers: list[nn.Module] = []
            channels = 3
            for width in widths:
                layers += [
                    nn.Conv2d(channels, width, 3, stride=2, padding=1, bias=False),
                    nn.BatchNorm2d(width),
                    nn.ReLU(inplace=True),
                ]
                channels = width
            self.body = nn.Sequential(*layers)

        def forward(self, pixels: torch.Tensor) -> torch.Tensor:
            return self.body(pixels).mean(dim=(2, 3))

    class FrozenClip(nn.Module):
        def __init__(self, clip_model: Any) -> None:
            super().__init__()
            self.clip = [clip_model]  # a list: kept out of the module tree and the state dict

        def forward(self, pixels: torch.Tensor) -> torch.Tensor:
            with torch.no_grad():
                return self.clip[0].encode_image(pixels).float()

    class EncoderNet(nn.Module):
        def __init__(self, features: nn.Module, head: nn.Module, dim: int) -> None:
            super().__init__()
            self.features = features
            self.head = head
            self.classifier = nn.Linear(dim, classes)

        def embed(self, pixels: torch.Tensor) -> torch.Tensor:
            embedding: torch.Tensor = self.head(self.features(pixels))
            return embedding

        def forward(self, pixels: torch.Tensor) -> torch.Tensor:
            logits: torch.Tensor = self.classifier(self.embed(pixels))
            return logits

    kind = architecture.get("kind")
    if kind == "cnn":
        widths = [int(w) for w in architecture["widths"]]
        # a batch-norm neck centres and scales the pooled features (a common offset would otherwise
        # put every cosine near 1); the classifier reads the same features the memory compares
        neck = (
            nn.BatchNorm1d(widths[-1], affine=False)
            if architecture.get("neck") == "batchnorm"
            else nn.Identity()
        )
        return EncoderNet(SmallCNN(widths), neck, widths[-1])
    if kind == "open_clip_head":
        if backbone is None:
            raise EncoderError("an open_clip_head encoder needs its open_clip image tower")
        dim = int(architecture["embedding_dim"])
        return EncoderNet(FrozenClip(backbone), nn.Linear(int(architecture["clip_dim"]), dim), dim)
    raise EncoderError(f"unknown trained-encoder architecture {kind!r} (expected 'cnn' or 'open_clip_head')")


def to_tensor(batch: np.ndarray, device: str) -> Any:
    """(N, S, S, 3) uint8 → (N, 3, S, S) float32 in [0, 1] on `device`."""
    with needs_extra("clip"):
        import torch

    return torch.from_numpy(np.ascontiguousarray(batch)).to(device).permute(0, 3, 1, 2).float().div_(255.0)


def normalizer(config: dict[str, Any], device: str) -> tuple[Any, Any]:
    """(mean, std) tensors shaped (1, 3, 1, 1) from an encoder config's `normalize`."""
    with needs_extra("clip"):
        import torch

    mean = torch.tensor(config["normalize"]["mean"], dtype=torch.float32, device=device).view(1, 3, 1, 1)
    std = torch.tensor(config["normalize"]["std"], dtype=torch.float32, device=device).view(1, 3, 1, 1)
    return mean, std


def _init_spec(init: str) -> Any:
    """The `open_clip:<model>:<weights>` EncoderSpec an `--init` string names."""
    try:
        spec = EncoderSpec.parse(init)
    except EncoderError as error:
        raise EncoderError(
            f"--init must be an open_clip:<model>:<weights> spec, got {init!r}: {error}"
        ) from error
    if spec.kind != OPEN_CLIP.name:
        raise EncoderError(f"--init must be an open_clip:<model>:<weights> spec, got {init!r}")
    return spec


def load_backbone(init: str, *, device: str | None) -> Any:
    """The project's OpenClipEncoder for an `open_clip:<model>:<weights>` init spec."""
    from robofailring.encoders.openclip import OpenClipEncoder

    spec = _init_spec(init)
    return OpenClipEncoder(spec.model, spec.weights, device=device)


def clip_input(backbone: Any) -> tuple[int, list[float], list[float]]:
    """(input size, mean, std) of an open_clip image tower, as its own preprocessing uses them."""
    size = backbone.model.visual.image_size
    size = int(size[0] if isinstance(size, (tuple, list)) else size)
    mean = [float(v) for v in getattr(backbone.model.visual, "image_mean", None) or (0.481, 0.458, 0.408)]
    std = [float(v) for v in getattr(backbone.model.visual, "image_std", None) or (0.269, 0.261, 0.276)]
    return size, mean, std


def read_encoder_config(directory: Path) -> dict[str, Any]:
    """The `encoder.json` of a trained-encoder folder, checked enough to name what is wrong."""
    path = Path(directory) / CONFIG_NAME
    if not Path(directory).is_dir():
        raise EncoderError(
            f"trained encoder folder {directory} does not exist (write one with `robofailring train-encoder`)"
        )
    try:
        text = path.read_bytes()
    except OSError as error:
        raise EncoderError(f"cannot read trained-encoder config {path}: {error}") from error
    config = parse_json(text, source=f"trained-encoder config {path}", error=EncoderError)
    if not isinstance(config, dict) or config.get("format") != FORMAT:
        raise EncoderError(f"{path} is not a trained-encoder config (format {FORMAT!r})")
    if config.get("format_version") != FORMAT_VERSION:
        raise EncoderError(
            f"{path} has format version {config.get('format_version')}, this version reads {FORMAT_VERSION}"
        )
    for key in ("architecture", "input_size", "normalize", "classes", "embedding_dim", "weights_digest"):
        if key not in config:
            raise EncoderError(f"{path} lacks {key!r}")
    check_trained_config(config, path)
    return config


def trained_identity(directory: Path) -> tuple[dict[str, Any], str]:
    """A trained-encoder folder's config and identity, checked without loading its network: the weights
    must match the config's digest and an `open_clip_head`'s tower must still be the one it was trained on."""
    config = read_encoder_config(directory)
    weights = Path(directory) / WEIGHTS_NAME
    if not weights.is_file():
        raise EncoderError(f"trained encoder {directory} has no {WEIGHTS_NAME}")
    digest = file_digest(weights)
    if digest != config["weights_digest"]:
        raise EncoderError(
            f"{weights} does not match the weights digest in {Path(directory) / CONFIG_NAME} "
            f"({digest} != {config['weights_digest']}): the folder was modified after training"
        )
    architecture = config["architecture"]
    tower = ""
    if architecture.get("kind") == "open_clip_head":
        from robofailring.encoders.openclip import checked_weights, open_clip_identity

        init = _init_spec(str(architecture["init"]))
        model_name, checkpoint = checked_weights(init.model, init.weights)
        tower = open_clip_identity(model_name, init.weights, checkpoint)
        if tower != architecture.get("init_identity"):
            raise EncoderError(
                f"trained encoder {directory} was trained on {architecture.get('init_identity')}, "
                f"but {architecture['init']} now loads {tower}"
            )
    normalize = json.dumps([config["normalize"]["mean"], config["normalize"]["std"]])  # it changes the output
    weights_id = hashlib.blake2b(f"{digest}|{tower}|{normalize}".encode(), digest_size=8).hexdigest()
    name = "cnn4" if architecture.get("kind") == "cnn" else "clip-head"
    return (
        config,
        f"trained:{name}-{int(config['input_size'])}px-{int(config['embedding_dim'])}d:{weights_id}",
    )


class TrainedEncoder:
    """A trained encoder folder, batched, on CUDA when available (see the module docstring)."""

    def __init__(self, directory: Path, *, device: str | None = None, batch_size: int = 256) -> None:
        with needs_extra("clip"):
            import torch

        from robofailring.encoders.device import pick_device

        self.directory = Path(directory).expanduser()
        self.config, self._identity = trained_identity(self.directory)
        weights = self.directory / WEIGHTS_NAME
        self._device = pick_device(device)
        self._batch_size = batch_size
        architecture = self.config["architecture"]
        backbone = None
        if architecture.get("kind") == "open_clip_head":
            backbone = load_backbone(str(architecture["init"]), device=self._device)
        self.network = build_network(
            architecture, len(self.config["classes"]), backbone.model if backbone else None
        )
        try:
            state = torch.load(weights, map_location=self._device, weights_only=True)
            self.network.load_state_dict(state)
        except Exception as error:  # torch raises several types for a bad file or state dict
            raise EncoderError(
                f"cannot load {weights} into its architecture {architecture}: {error}"
            ) from error
        self.network.to(self._device).eval()
        self._mean, self._std = normalizer(self.config, self._device)
        self._dim = int(self.config["embedding_dim"])
        self._size = int(self.config["input_size"])
        self._torch = torch

    @property
    def identity(self) -> str:
        return self._identity

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def device(self) -> str:
        return self._device

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            return np.zeros((0, self._dim), dtype=np.float32)
        outputs = []
        with self._torch.inference_mode():
            for start in range(0, len(images), self._batch_size):
                batch = prepare_images(images[start : start + self._batch_size], self._size)
                pixels = (to_tensor(batch, self._device) - self._mean) / self._std
                outputs.append(self.network.embed(pixels).float().cpu().numpy())
        return l2_normalize(np.concatenate(outputs))


def load(spec: EncoderSpec, device: str | None) -> TrainedEncoder:
    """The kind's encoder (`spec.py`)."""
    return TrainedEncoder(Path(spec.directory), device=device)


def export_identity(spec: EncoderSpec) -> tuple[str, str]:
    _, identity = trained_identity(Path(spec.directory).expanduser())
    return identity, identity


def network(spec: EncoderSpec) -> Network:
    """The whole trained network (a CLIP tower and its head included) from normalised pixels to `embed`."""
    with needs_extra("clip"):
        from torch import nn

    trained = TrainedEncoder(Path(spec.directory).expanduser(), device="cpu")

    class Embed(nn.Module):
        def __init__(self, network: Any) -> None:
            super().__init__()
            self.network: Any = network

        def forward(self, pixels: Any) -> Any:
            return self.network.embed(pixels)

    normalize = trained.config["normalize"]
    side = int(trained.config["input_size"])
    preprocess = {"kind": "square", "size": side, "mean": normalize["mean"], "std": normalize["std"]}
    return Network(Embed(trained.network).eval(), side, preprocess, trained.identity, trained.dim)
