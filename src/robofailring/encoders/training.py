"""Training a `trained:<DIR>` encoder on the frames of one split of the user's own runs.

Every frame of every view of the chosen split is one sample; its class is
failure type × progress bucket × view (successes are their own type), so the network must tell
what went wrong, how far the run is and which camera looks, while photometric augmentation
(brightness, contrast, saturation, colour gains, offsets) and small shifts and scalings keep it from keying
on lighting and exact framing. The test split is refused: an encoder must never see the frames
it is evaluated on. Extra datasets (`extra_data`, e.g. simulated episodes under random looks) add
every frame of every split, labelled the same way: they are training data only. Training is
deterministic for a seed on a given device and thread count.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.atomic import atomic_directory
from robofailring.data.grounding import failure_type
from robofailring.data.images import decode_image
from robofailring.data.layouts import load_dataset
from robofailring.data.model import Frame, Outcome, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.data.splits import split_of
from robofailring.encoders.augment import AUGMENTATION, augment
from robofailring.encoders.device import check_device_name
from robofailring.encoders.trained import (
    CNN_MEAN,
    CNN_STD,
    CNN_WIDTHS,
    CONFIG_NAME,
    FORMAT,
    FORMAT_VERSION,
    WEIGHTS_NAME,
    build_network,
    clip_input,
    file_digest,
    load_backbone,
    normalizer,
    prepare_images,
    to_tensor,
)
from robofailring.errors import DataError, SettingError
from robofailring.extras import needs_extra
from robofailring.jsontext import parse_json
from robofailring.outputs import check_folder
from robofailring.progress import progress_bar

HELD_OUT_SPLITS: Final[frozenset[str]] = frozenset({"test", "ood"})


@dataclass(frozen=True)
class TrainEncoderConfig:
    # the dataset (any layout) and how it is read (labels, task, views); only the frames of `split` are
    # read. A path is taken as `DataSelection(path)`
    data: DataSelection
    out: Path  # encoder folder to write (atomically): encoder.json + weights.pt
    split: str = "train"  # never a held-out split (test, ood)
    image_size: int = 64  # CNN input side in pixels (with `init`: the CLIP tower's own size)
    epochs: int = 10
    batch_size: int = 128
    learning_rate: float = 3e-3
    seed: int = 0
    progress_buckets: int = 4  # progress quarters: 0–25 %, 25–50 %, …
    frame_stride: int = 2  # every n-th frame of each view (neighbouring frames are near copies)
    embedding_dim: int = 256  # with `init`: the projection's output size
    init: str | None = None  # open_clip:<model>:<weights>: train a projection head on that frozen tower
    test_fraction: float = 0.5  # layouts without splits use the evaluation's hash split
    device: str | None = None  # where the training runs (default: cuda when available)
    threads: int | None = (
        None  # torch CPU threads (default: half the cores, at least 1: the machine is shared)
    )
    # more training datasets, every split of each (never test data), read with the data's views
    extra_data: tuple[Path, ...] = ()

    def __post_init__(self) -> None:  # bad settings fail before any frame is read
        if not isinstance(self.data, DataSelection):
            object.__setattr__(self, "data", DataSelection(Path(self.data)))
        object.__setattr__(self, "extra_data", tuple(Path(root) for root in self.extra_data))
        if self.data.root.resolve() in {root.resolve() for root in self.extra_data}:
            raise SettingError(
                f"{self.data.root} is both the training data and an extra dataset: every split of an extra "
                "dataset is trained on, so its held-out frames would be seen"
            )
        if self.split in HELD_OUT_SPLITS:
            raise SettingError(
                f"refusing to train an encoder on the {self.split!r} split: it is held out for evaluation, "
                "and an encoder must never see the frames it is tested on (use --split train)"
            )
        if self.epochs < 1 or self.batch_size < 2 or self.progress_buckets < 1 or self.frame_stride < 1:
            raise SettingError(
                "epochs ≥ 1, batch size ≥ 2, progress buckets ≥ 1 and frame stride ≥ 1 are required"
            )
        if self.image_size < 16:
            raise SettingError(f"image size must be at least 16 px, got {self.image_size}")
        if not self.learning_rate > 0:
            raise SettingError(f"learning rate must be positive, got {self.learning_rate}")
        check_device_name(self.device)

    def recipe(self) -> dict[str, Any]:
        """The settings that decide the weights (not where they go or how fast), as encoders trained before
        the data was one value recorded them (the same recipe reuses them)."""
        settings: dict[str, Any] = {"data": str(self.data.root.resolve())}
        for field in fields(self):
            if field.name not in ("data", "out", "device", "threads", "extra_data"):
                settings[field.name] = getattr(self, field.name)
        settings["views"] = self.data.views
        if self.extra_data:  # absent when none: encoders trained before `extra_data` keep their recipe
            settings["extra_data"] = [str(root.resolve()) for root in self.extra_data]
        if self.data.labels is not None:  # likewise (the labels' content is in the frames' digest)
            settings["labels"] = str(self.data.labels.resolve())
        if self.data.task is not None:
            settings["task"] = self.data.task
        return settings


@dataclass(frozen=True)
class Sample:
    frame: Frame
    label: str  # `<failure type>|p<bucket>|<view>`


def _kind(trajectory: Trajectory) -> str | None:
    if trajectory.symbol:
        return failure_type(trajectory.symbol)
    if trajectory.outcome is Outcome.SUCCESS:
        return "success"
    if trajectory.outcome is Outcome.FAILURE:
        return "failure"
    return None  # unlabelled: nothing to learn from


def training_trajectories(config: TrainEncoderConfig) -> list[Trajectory]:
    """The trajectories of the chosen split of `config.data` (the extra datasets not included)."""
    trajectories = list(config.data.load().trajectories())
    has_splits = any(t.split for t in trajectories)
    return [
        t
        for t in trajectories
        if split_of(t, has_splits=has_splits, test_fraction=config.test_fraction) == config.split
    ]


@dataclass(frozen=True)
class TrainingSet:
    """What an encoder trains on: the chosen split of its data, then every split of each extra dataset."""

    samples: list[Sample]
    trajectories: int
    skipped: list[str]  # keys of unlabelled trajectories (nothing to learn from)
    extra: list[dict[str, Any]]  # per extra dataset: its root, trajectories and frames


def training_samples(config: TrainEncoderConfig) -> TrainingSet:
    """The labelled samples of the chosen split of `config.data` and of every split of each extra dataset."""
    samples, used, skipped = _labelled(training_trajectories(config), config)
    if not samples:
        raise DataError(f"no labelled frames in split {config.split!r} of {config.data.root}")
    extra = []
    for root in config.extra_data:
        more, count, unlabelled = _labelled(
            list(load_dataset(root, views=config.data.views).trajectories()), config
        )
        if not more:
            raise DataError(f"no labelled frames in the extra training dataset {root}")
        samples, used, skipped = samples + more, used + count, skipped + unlabelled
        extra.append({"data": str(root.resolve()), "trajectories": count, "frames": len(more)})
    return TrainingSet(samples, used, skipped, extra)


def _labelled(
    trajectories: list[Trajectory], config: TrainEncoderConfig
) -> tuple[list[Sample], int, list[str]]:
    """(samples, trajectories used, keys of unlabelled trajectories skipped)."""
    samples: list[Sample] = []
    skipped: list[str] = []
    used = 0
    for trajectory in trajectories:
        kind = _kind(trajectory)
        if kind is None:
            skipped.append(trajectory.key)
            continue
        used += 1
        for view, frames in trajectory.views.items():
            for t in range(0, len(frames), config.frame_stride):
                bucket = min(int(config.progress_buckets * t / len(frames)), config.progress_buckets - 1)
                samples.append(Sample(frames[t], f"{kind}|p{bucket}|{view}"))
    return samples, used, skipped


def _read(samples: list[Sample], size: int) -> tuple[np.ndarray, str]:
    """(N, size, size, 3) uint8 frames and the digest of the labels and image bytes read."""
    digest = hashlib.blake2b(digest_size=16)
    images = np.empty((len(samples), size, size, 3), dtype=np.uint8)
    with progress_bar(total=len(samples), desc="reading frames", unit="frame") as bar:
        for i, sample in enumerate(samples):
            data = sample.frame.read_bytes()
            if data is None:
                image = sample.frame.load()
                data = str(image.shape).encode() + image.tobytes()
            else:
                image = decode_image(data, source=sample.frame.reference)
            digest.update(sample.label.encode() + b"\0" + hashlib.blake2b(data, digest_size=16).digest())
            images[i] = prepare_images([image], size)[0]
            bar.update(1)
    return images, digest.hexdigest()


def _architecture(config: TrainEncoderConfig) -> tuple[dict[str, Any], Any, int, list[float], list[float]]:
    """(architecture, frozen backbone or None, input size, mean, std)."""
    if config.init is None:
        architecture: dict[str, Any] = {"kind": "cnn", "widths": list(CNN_WIDTHS), "neck": "batchnorm"}
        return architecture, None, config.image_size, list(CNN_MEAN), list(CNN_STD)
    backbone = load_backbone(config.init, device=config.device)
    size, mean, std = clip_input(backbone)
    architecture = {
        "kind": "open_clip_head",
        "init": config.init,
        "init_identity": backbone.identity,
        "clip_dim": backbone.dim,
        "embedding_dim": config.embedding_dim,
    }
    return architecture, backbone, size, mean, std


def existing_encoder(out: Path) -> dict[str, Any] | None:
    """The encoder.json at `out`, None when `out` is absent or empty; refuses to replace anything else."""
    check_folder(out, holds="a trained encoder")
    if not out.exists():
        return None
    try:
        config = parse_json((out / CONFIG_NAME).read_bytes(), source=str(out / CONFIG_NAME))
    except (OSError, DataError):
        config = None
    if isinstance(config, dict) and config.get("format") == FORMAT:
        return config
    if any(out.iterdir()):
        raise DataError(
            f"{out} exists and is not a trained-encoder folder; refusing to replace it "
            "(choose another --out or remove it)"
        )
    return None


def train_encoder(
    config: TrainEncoderConfig, *, reuse: bool = False, say: Callable[[str], None] | None = None
) -> Path:
    """Train an encoder and write `config.out` atomically; returns that folder (`trained:<it>` loads it).

    With `reuse`, a folder already holding an encoder of the same recipe trained on the same
    frames (labels and image bytes) is returned as it is.
    """
    with needs_extra("clip"):
        import torch

    from robofailring.encoders.device import pick_device

    out = Path(config.out)
    previous = existing_encoder(out)
    found = training_samples(config)
    samples = found.samples
    architecture, backbone, size, mean, std = _architecture(config)
    images, data_digest = _read(samples, size)
    training = previous.get("training", {}) if previous else {}
    if reuse and training.get("recipe") == config.recipe() and training.get("data_digest") == data_digest:
        if say:
            say(f"reusing the trained encoder {out} (same recipe, same {len(samples)} frames)")
        return out
    classes = sorted({sample.label for sample in samples})
    labels = torch.tensor([classes.index(s.label) for s in samples], dtype=torch.long)
    device = pick_device(config.device)
    previous_threads = torch.get_num_threads()
    threads = config.threads or max(1, (os.cpu_count() or 1) // 2)
    torch.set_num_threads(threads)
    try:
        torch.manual_seed(config.seed)
        generator = torch.Generator().manual_seed(config.seed)
        network = build_network(architecture, len(classes), backbone.model if backbone else None).to(device)
        norm = {"normalize": {"mean": mean, "std": std}}
        mean_t, std_t = normalizer(norm, device)

        def batches(order: Any) -> Any:
            for start in range(0, len(order), config.batch_size):
                index = order[start : start + config.batch_size]
                yield to_tensor(images[index.numpy()], device), labels[index].to(device)

        def evaluate() -> tuple[float, float]:
            network.eval()
            loss_sum, correct = 0.0, 0
            with torch.inference_mode():
                for pixels, target in batches(torch.arange(len(samples))):
                    logits = network((pixels - mean_t) / std_t)
                    loss_sum += float(torch.nn.functional.cross_entropy(logits, target, reduction="sum"))
                    correct += int((logits.argmax(dim=1) == target).sum())
            return loss_sum / len(samples), correct / len(samples)

        initial_loss, _ = evaluate()
        trainable = [p for p in network.parameters() if p.requires_grad]
        optimizer = torch.optim.AdamW(trainable, lr=config.learning_rate, weight_decay=1e-4)
        steps = config.epochs * math.ceil(len(samples) / config.batch_size)
        schedule = torch.optim.lr_scheduler.OneCycleLR(
            optimizer, max_lr=config.learning_rate, total_steps=steps, pct_start=0.2
        )
        history: list[float] = []
        started = time.perf_counter()
        with progress_bar(total=steps, desc="training encoder", unit="batch") as bar:
            for _ in range(config.epochs):
                network.train()
                epoch_loss = 0.0
                for pixels, target in batches(torch.randperm(len(samples), generator=generator)):
                    augmented = augment(pixels.cpu(), generator).to(device)
                    loss = torch.nn.functional.cross_entropy(network((augmented - mean_t) / std_t), target)
                    optimizer.zero_grad(set_to_none=True)
                    loss.backward()
                    optimizer.step()
                    schedule.step()
                    epoch_loss += float(loss.detach()) * len(target)
                    bar.update(1)
                history.append(epoch_loss / len(samples))
        seconds = time.perf_counter() - started
        final_loss, accuracy = evaluate()
        state = {k: v.cpu() for k, v in network.state_dict().items()}
    finally:
        torch.set_num_threads(previous_threads)
    record = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "architecture": architecture,
        "input_size": size,
        "embedding_dim": int(architecture.get("embedding_dim", CNN_WIDTHS[-1])),
        "normalize": {"mean": mean, "std": std},
        "labels": "failure type × progress bucket × view (successes as their own type)",
        "classes": classes,
        "training": {
            "recipe": config.recipe(),
            "data_digest": data_digest,
            "frames": len(samples),
            "trajectories": found.trajectories,
            "extra_data": found.extra,
            "skipped_unlabelled": found.skipped,
            "augmentation": AUGMENTATION,
            "device": device,
            "threads": threads,
            "seconds": round(seconds, 2),
            "loss_history": [round(v, 6) for v in history],
            "initial_loss": round(initial_loss, 6),
            "final_loss": round(final_loss, 6),
            "final_train_accuracy": round(accuracy, 6),
        },
    }
    with atomic_directory(out) as folder:
        torch.save(state, folder / WEIGHTS_NAME)
        record["weights_digest"] = file_digest(folder / WEIGHTS_NAME)
        (folder / CONFIG_NAME).write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    if say:
        extra_frames = sum(extra["frames"] for extra in found.extra)
        say(
            f"trained encoder {out}: {len(samples)} frames of {found.trajectories} trajectories"
            + (f" ({extra_frames} of them from extra data)" if found.extra else "")
            + f", {len(classes)} classes, "
            f"{config.epochs} epochs in {seconds:.1f} s on {device} ({threads} threads), "
            f"training accuracy {100 * accuracy:.1f} %"
        )
    return out
