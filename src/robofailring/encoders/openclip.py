"""The real open_clip path: a model by name plus a pretrained tag or a local checkpoint file."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.encoders.base import file_digest, l2_normalize
from robofailring.encoders.device import pick_device
from robofailring.encoders.spec import EncoderSpec, Network
from robofailring.errors import EncoderError, WeightsUnavailableError
from robofailring.extras import needs_extra
from robofailring.jsontext import parse_json

_HOW_TO_PROVIDE = (
    "No weights can be downloaded on this machine. Provide them in one of two ways: "
    '(1) on a machine with internet, run `python -c "import open_clip; '
    "open_clip.create_model_and_transforms('{model}', pretrained='{tag}')\"` and copy the Hugging Face "
    "cache (~/.cache/huggingface) here, or set HF_HUB_CACHE to a folder that holds it; "
    "(2) pass a local checkpoint file: `open_clip:{model}:/path/to/checkpoint.pt` "
    "(a state_dict saved with torch.save, or an open_clip .bin/.safetensors file)."
)


def _resolve_model_name(model: str) -> str:
    """A model name, or a path to an open_clip model-config JSON that is registered first."""
    with needs_extra("clip"):
        import open_clip

    candidate = Path(model)
    if candidate.suffix == ".json":
        if not candidate.is_file():
            raise EncoderError(f"open_clip model config {candidate} does not exist")
        try:
            text = candidate.read_bytes()
        except OSError as error:
            raise EncoderError(f"cannot read open_clip model config {candidate}: {error}") from error
        parse_json(text, source=f"open_clip model config {candidate}", error=EncoderError)
        open_clip.add_model_config(candidate)
        return candidate.stem
    if model not in open_clip.list_models():
        raise EncoderError(
            f"unknown open_clip model {model!r}; known models include "
            f"{', '.join(m for m in open_clip.list_models() if m.startswith('ViT-'))[:400]}…"
        )
    return model


def _hub_reachable(host: str = "huggingface.co", timeout: float = 3.0) -> bool:
    """Whether the model hub's name resolves (no network here: fail fast instead of retrying)."""
    import concurrent.futures
    import socket

    pool = concurrent.futures.ThreadPoolExecutor(max_workers=1)
    try:
        pool.submit(socket.getaddrinfo, host, 443).result(timeout=timeout)
        return True
    except Exception:
        return False
    finally:
        pool.shutdown(wait=False)


@contextlib.contextmanager
def _offline_unless_reachable() -> Iterator[None]:
    """Let open_clip use only the local Hugging Face cache when the hub cannot be reached."""
    try:
        import huggingface_hub.constants as hub_constants
    except ImportError:
        yield
        return
    previous = hub_constants.HF_HUB_OFFLINE
    if not previous and not _hub_reachable():
        hub_constants.HF_HUB_OFFLINE = True
    try:
        yield
    finally:
        hub_constants.HF_HUB_OFFLINE = previous


def _checkpoint_problem(error: Exception) -> str:
    """What is wrong with a checkpoint file, in words (torch's own messages run to paragraphs)."""
    text = str(error)
    if any(marker in text for marker in ("size mismatch", "Missing key", "Unexpected key")):
        return "its tensors do not fit this model (a checkpoint of another architecture?)"
    unreadable = (
        "Weights only load failed",
        "load key",
        "central directory",
        "Unsupported operand",
        "header",
    )
    if isinstance(error, (EOFError, UnicodeDecodeError)) or any(marker in text for marker in unreadable):
        return "it is not a PyTorch state dict (.pt/.pth/.bin) or safetensors file, or it is truncated"
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return f"{type(error).__name__}: {lines[0] if lines else 'no detail'}"


def checked_weights(model: str, weights: str) -> tuple[str, Path | None]:
    """The open_clip model name and the checkpoint file (None for a pretrained tag) a spec names, checked
    without loading anything; an EncoderError says what is wrong and how to provide weights."""
    with needs_extra("clip"):
        import open_clip

    if not weights:
        raise EncoderError(
            f"open_clip:{model} needs weights: a pretrained tag or a checkpoint file. "
            + _HOW_TO_PROVIDE.format(model=model, tag="openai")
        )
    model_name = _resolve_model_name(model)
    weights_path = Path(weights).expanduser()
    is_file = weights_path.suffix in {".pt", ".pth", ".bin", ".safetensors", ".ckpt"} or weights_path.exists()
    if is_file and not weights_path.is_file():
        raise EncoderError(
            f"checkpoint file {weights_path} does not exist. "
            + _HOW_TO_PROVIDE.format(model=model_name, tag="openai")
        )
    if not is_file and weights not in open_clip.list_pretrained_tags_by_model(model_name):
        tags = open_clip.list_pretrained_tags_by_model(model_name)
        raise EncoderError(
            f"{weights!r} is neither a checkpoint file nor a pretrained tag of {model_name}; "
            f"its tags are {tags}"
        )
    return model_name, weights_path if is_file else None


def open_clip_identity(model_name: str, weights: str, checkpoint: Path | None) -> str:
    """`open_clip:<model>:<tag>` or `open_clip:<model>:file-<digest of the checkpoint file>`."""
    return f"open_clip:{model_name}:" + (f"file-{file_digest(checkpoint)}" if checkpoint else weights)


class OpenClipEncoder:
    """An open_clip image tower, batched, on CUDA when available."""

    def __init__(self, model: str, weights: str, *, device: str | None = None, batch_size: int = 64) -> None:
        with needs_extra("clip"):
            import open_clip
            import torch

        model_name, checkpoint = checked_weights(model, weights)
        is_file = checkpoint is not None
        weights_path = checkpoint if checkpoint is not None else Path(weights)
        self._device = pick_device(device)
        self._batch_size = batch_size
        try:
            with _offline_unless_reachable():
                created: Any = open_clip.create_model_and_transforms(
                    model_name, pretrained=str(weights_path) if is_file else weights, device=self._device
                )
        except Exception as error:  # open_clip raises many types when weights are missing
            if is_file:
                raise EncoderError(
                    f"cannot load checkpoint {weights_path} into open_clip model {model_name}: "
                    + _checkpoint_problem(error)
                ) from error
            raise WeightsUnavailableError(
                f"weights for open_clip:{model_name}:{weights} are not available here ({type(error).__name__}). "
                + _HOW_TO_PROVIDE.format(model=model_name, tag=weights)
            ) from error
        self.model, _, self.preprocess = created
        self.model.eval()
        self._identity = open_clip_identity(model_name, weights, checkpoint)
        self._torch = torch
        self._dim = self._embedding_width(open_clip.get_model_config(model_name) or {})

    def _embedding_width(self, config: dict[str, Any]) -> int:
        """The image embedding's width: the tower's `output_dim` where it has one, else the model config's
        `embed_dim` (a timm tower, as SigLIP's and the ConvNeXt CLIPs' are, has none), else one forward pass."""
        width = getattr(self.model.visual, "output_dim", None)
        if isinstance(width, int):
            return width
        if isinstance(config.get("embed_dim"), int):
            return int(config["embed_dim"])
        return int(self.encode_raw([np.zeros((32, 32, 3), np.uint8)]).shape[1])

    @property
    def identity(self) -> str:
        return self._identity

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def device(self) -> str:
        return self._device

    def preprocess_batch(self, images: Sequence[np.ndarray]) -> Any:
        """open_clip's own preprocessing (resize, centre crop, normalise) stacked into one tensor."""
        with needs_extra("clip"):
            from PIL import Image

        return self._torch.stack([self.preprocess(Image.fromarray(image)) for image in images])

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            return np.zeros((0, self._dim), dtype=np.float32)
        return l2_normalize(self.encode_raw(images))

    def encode_raw(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """The image tower's features of `images`, not normalised."""
        outputs = []
        with self._torch.inference_mode():
            for start in range(0, len(images), self._batch_size):
                batch = self.preprocess_batch(images[start : start + self._batch_size]).to(self._device)
                features = self.model.encode_image(batch)
                outputs.append(features.float().cpu().numpy())
        return np.concatenate(outputs)


def load(spec: EncoderSpec, device: str | None) -> OpenClipEncoder:
    """The kind's encoder (`spec.py`)."""
    return OpenClipEncoder(spec.model, spec.weights, device=device)


def export_identity(spec: EncoderSpec) -> tuple[str, str]:
    """The identity, and what an export is made from: it and the model-config file a spec may name."""
    model_name, checkpoint = checked_weights(spec.model, spec.weights)
    identity = open_clip_identity(model_name, spec.weights, checkpoint)
    config = Path(spec.model)
    return identity, identity + (f"|config-{file_digest(config)}" if config.suffix == ".json" else "")


def network(spec: EncoderSpec) -> Network:
    """The image tower alone, on the CPU (the text tower is freed before the export copies it)."""
    clip = OpenClipEncoder(spec.model, spec.weights, device="cpu")
    visual, identity, dim = clip.model.visual, clip.identity, clip.dim
    del clip
    preprocess = {"kind": "open_clip", **json.loads(json.dumps(visual.preprocess_cfg))}
    size = visual.image_size
    side = int(size[0] if isinstance(size, (tuple, list)) else size)
    return Network(visual, side, preprocess, identity, dim)
