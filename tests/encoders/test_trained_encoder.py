"""The trained encoder: `train-encoder` on a tiny project dataset, then `trained:<DIR>` as any encoder."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from synthetic import synthetic_frame, write_episode, write_labelled_runs, write_project_dataset
from typer.testing import CliRunner

from robofailring import (
    CachedEncoder,
    EncoderError,
    FailureDetector,
    FailureMemory,
    load_dataset,
    load_encoder,
)
from robofailring.cli.verbs import app
from robofailring.data.selection import DataSelection
from robofailring.encoders import encoder_slug
from robofailring.encoders.trained import CONFIG_NAME, WEIGHTS_NAME
from robofailring.encoders.training import TrainEncoderConfig, train_encoder, training_samples
from robofailring.errors import DataError, EncoderMismatchError, SettingError

pytestmark = pytest.mark.slow  # trains with torch: the fast lane never imports it (tests/conftest.py)

runner = CliRunner()


def _config(data: Path, out: Path, *, labels: Path | None = None, **changes: object) -> TrainEncoderConfig:
    settings: dict[str, object] = {
        "image_size": 32,
        "epochs": 2,
        "batch_size": 32,
        "frame_stride": 1,
        "threads": 1,
    }
    settings.update(changes)
    return TrainEncoderConfig(data=DataSelection(data, labels=labels), out=out, **settings)  # type: ignore[arg-type]


def _images() -> list[np.ndarray]:
    return [synthetic_frame("pick_cube", "slip_wp3" if i % 2 else None, i % 3, i, 6) for i in range(6)]


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """(dataset, encoder of seed 0, the same recipe trained again) on a tiny project dataset."""
    root = tmp_path_factory.mktemp("trained")
    data = write_project_dataset(root / "data")
    first = train_encoder(_config(data, root / "seed0"))
    again = train_encoder(_config(data, root / "seed0-again"))
    return data, first, again


def test_training_is_deterministic_by_seed_and_lowers_its_loss(trained: tuple[Path, Path, Path]) -> None:
    _, first, again = trained
    record = json.loads((first / CONFIG_NAME).read_text())
    assert record["weights_digest"] == json.loads((again / CONFIG_NAME).read_text())["weights_digest"]
    assert (first / WEIGHTS_NAME).read_bytes() == (again / WEIGHTS_NAME).read_bytes()
    np.testing.assert_array_equal(
        load_encoder(f"trained:{first}").encode(_images()), load_encoder(f"trained:{again}").encode(_images())
    )
    training = record["training"]
    assert training["final_loss"] < training["initial_loss"]
    assert training["loss_history"][-1] < training["loss_history"][0]
    assert record["input_size"] == 32 and record["training"]["recipe"]["epochs"] == 2
    assert record["architecture"] == {"kind": "cnn", "widths": [32, 64, 128, 256], "neck": "batchnorm"}
    # labels: failure type × progress quarter × view, successes their own type; only the training split
    assert {c.split("|")[0] for c in record["classes"]} == {"grasp", "slip", "wrong_object", "success"}
    assert {c.split("|")[1] for c in record["classes"]} == {"p0", "p1", "p2", "p3"}
    assert len(record["classes"]) == 4 * 4 * 3
    assert training["trajectories"] == 16 and training["frames"] == 16 * 3 * 6
    assert 0.0 <= training["final_train_accuracy"] <= 1.0


def test_only_the_chosen_split_is_read_and_held_out_splits_are_refused(
    trained: tuple[Path, Path, Path],
) -> None:
    data, _, _ = trained
    found = training_samples(_config(data, data / "unused"))
    train_files = {
        frame.reference
        for t in load_dataset(data).select(split="train")
        for frames in t.views.values()
        for frame in frames
    }
    assert found.trajectories == 16 and {s.frame.reference for s in found.samples} == train_files
    assert found.extra == []
    for held_out in ("test", "ood"):
        with pytest.raises(SettingError, match=f"refusing to train an encoder on the '{held_out}' split"):
            _config(data, data / "unused", split=held_out)
    result = runner.invoke(app, ["train-encoder", str(data), "--out", str(data / "never"), "--split", "test"])
    assert result.exit_code == 2 and "held out for evaluation" in result.output
    assert not (data / "never").exists()


def test_a_labels_file_labels_the_frames_and_names_the_split(tmp_path: Path) -> None:
    data = tmp_path / "runs"
    rows = ["episode,task,outcome,symbol,split"]
    for index, symbol in enumerate((None, "slip_wp3", None, "grasp_wp2")):
        write_episode(data / f"run_{index}", "pick_cube", symbol, length=4)
        split = "train" if index < 2 else "test"
        rows.append(f"run_{index},pick_cube,{'failure' if symbol else 'success'},{symbol or ''},{split}")
    labels = tmp_path / "labels.csv"
    labels.write_text("\n".join(rows) + "\n")
    with pytest.raises(DataError, match="a task column in the --labels file"):
        training_samples(_config(data, tmp_path / "unused"))  # image episodes name neither task nor outcome
    found = training_samples(_config(data, tmp_path / "unused", labels=labels))
    assert found.trajectories == 2 and {s.label.split("|")[0] for s in found.samples} == {"success", "slip"}
    said: list[str] = []
    for _ in range(2):  # the labels file is part of the recipe, so a second run reuses the first's weights
        trained = train_encoder(_config(data, tmp_path / "enc", labels=labels), reuse=True, say=said.append)
    assert json.loads((trained / CONFIG_NAME).read_text())["training"]["recipe"]["labels"] == str(
        labels.resolve()
    )
    assert any(line.startswith("reusing the trained encoder") for line in said)


def test_trained_encoder_round_trips_and_its_identity_follows_its_weights(
    trained: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, first, _ = trained
    encoder = load_encoder(f"trained:{first}")
    embeddings = encoder.encode(_images())
    assert embeddings.shape == (6, 256) and embeddings.dtype == np.float32 and encoder.dim == 256
    np.testing.assert_allclose(np.linalg.norm(embeddings, axis=1), 1.0, atol=1e-5)
    assert float(embeddings[0] @ embeddings[1]) < 0.999  # different frames, different embeddings
    moved = shutil.copytree(first, tmp_path / "moved")
    reloaded = load_encoder(f"trained:{moved}")
    assert reloaded.identity == encoder.identity and encoder.identity.startswith("trained:cnn4-32px-256d:")
    np.testing.assert_allclose(reloaded.encode(_images()), embeddings, atol=1e-6)
    # a batch gives the same embeddings as one image at a time
    np.testing.assert_allclose(encoder.encode(_images()[:1])[0], embeddings[0], atol=1e-5)

    other = load_encoder(f"trained:{train_encoder(_config(data, tmp_path / 'seed1', seed=1))}")
    assert other.identity != encoder.identity
    assert encoder_slug(other.identity) != encoder_slug(encoder.identity)
    assert not np.allclose(other.encode(_images()), embeddings, atol=1e-3)

    (moved / WEIGHTS_NAME).write_bytes((tmp_path / "seed1" / WEIGHTS_NAME).read_bytes())
    with pytest.raises(EncoderError, match="does not match the weights digest"):
        load_encoder(f"trained:{moved}")
    with pytest.raises(EncoderError, match="does not exist"):
        load_encoder(f"trained:{tmp_path / 'nowhere'}")


def test_a_memory_built_with_it_refuses_another_encoder(
    trained: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, first, _ = trained
    encoder = CachedEncoder(load_encoder(f"trained:{first}"), cache_dir=tmp_path / "cache")
    memory, _ = FailureMemory.build(load_dataset(data).select(split="train"), encoder)
    assert memory.dim == 512 and memory.encoder == encoder.identity
    memory.save(tmp_path / "memory")
    loaded = FailureMemory.load(tmp_path / "memory")
    FailureDetector(loaded, encoder)  # its own encoder is accepted
    for spec in ("pixels", f"trained:{train_encoder(_config(data, tmp_path / 'seed2', seed=2))}"):
        with pytest.raises(EncoderMismatchError, match="built with encoder 'trained:cnn4"):
            FailureDetector(loaded, CachedEncoder(load_encoder(spec), cache_dir=tmp_path / "cache"))


def test_train_encoder_verb_and_reuse(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=4)
    out = tmp_path / "encoder"
    args = ["train-encoder", str(data), "--out", str(out), "--image-size", "24", "--epochs", "1"]
    result = runner.invoke(app, [*args, "--threads", "1"])
    assert result.exit_code == 0, result.output
    assert f"--encoder trained:{out}" in result.output and "training accuracy" in result.output
    record = json.loads((out / CONFIG_NAME).read_text())
    assert record["input_size"] == 24 and record["training"]["recipe"]["split"] == "train"
    said: list[str] = []
    config = TrainEncoderConfig(data=data, out=out, image_size=24, epochs=1)  # the verb's recipe
    assert train_encoder(config, reuse=True, say=said.append) == out
    assert said and said[0].startswith("reusing")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("keep me")
    refused = runner.invoke(
        app, ["train-encoder", str(data), "--out", str(tmp_path / "other"), "--epochs", "1"]
    )
    assert refused.exit_code == 2 and "refusing to replace it" in refused.output
    assert (tmp_path / "other" / "notes.txt").read_text() == "keep me"


def test_train_encoder_randomize_adds_simulated_episodes_to_its_recipe_and_frames(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROBOFAILRING_CACHE", str(tmp_path / "cache"))
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=4)
    args = ["--image-size", "24", "--epochs", "1", "--threads", "1", "--workers", "1"]
    plain = runner.invoke(app, ["train-encoder", str(data), "--out", str(tmp_path / "plain"), *args])
    randomized = runner.invoke(
        app, ["train-encoder", str(data), "--out", str(tmp_path / "random"), "--randomize", "8", *args]
    )
    assert plain.exit_code == 0 and randomized.exit_code == 0, randomized.output
    assert "randomised looks: dataset" in randomized.output and "8 episodes" in randomized.output
    without = json.loads((tmp_path / "plain" / CONFIG_NAME).read_text())["training"]
    with_random = json.loads((tmp_path / "random" / CONFIG_NAME).read_text())["training"]
    (simulated,) = (tmp_path / "cache" / "encoder-extra-data").iterdir()
    assert simulated.name.startswith("random-")
    manifest = json.loads((simulated / "manifest.json").read_text())
    assert manifest["look"] == "random" and manifest["tasks"] == ["pick_cube"]
    assert manifest["image_size"] == 48 and manifest["config"]["frames"] == 4  # the data's own
    assert manifest["config"]["seed"] == 5000  # RANDOMIZE_SEED + the training seed 0
    # 8 episodes, one per kind, three views, frames 0 and 2 of 4 (stride 2)
    assert with_random["extra_data"] == [{"data": str(simulated), "trajectories": 8, "frames": 8 * 3 * 2}]
    assert without["extra_data"] == [] and "extra_data" not in without["recipe"]
    assert with_random["recipe"]["extra_data"] == [str(simulated)]
    assert with_random["frames"] == without["frames"] + 48
    assert with_random["trajectories"] == without["trajectories"] + 8
    assert with_random["data_digest"] != without["data_digest"]


def test_projection_head_on_a_frozen_clip(tiny_checkpoint: tuple[Path, Path], tmp_path: Path) -> None:
    config_json, checkpoint = tiny_checkpoint
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=4)
    init = f"open_clip:{config_json}:{checkpoint}"
    out = train_encoder(_config(data, tmp_path / "head", init=init, embedding_dim=8))
    record = json.loads((out / CONFIG_NAME).read_text())
    assert record["architecture"]["kind"] == "open_clip_head" and record["input_size"] == 32
    assert record["architecture"]["init_identity"] == load_encoder(init).identity
    assert record["training"]["final_loss"] < record["training"]["initial_loss"]
    encoder = load_encoder(f"trained:{out}")
    assert encoder.dim == 8 and encoder.identity.startswith("trained:clip-head-32px-8d:")
    embeddings = encoder.encode(_images())
    assert embeddings.shape == (6, 8)
    np.testing.assert_allclose(np.linalg.norm(embeddings, axis=1), 1.0, atol=1e-5)
    # only the head and the classifier are stored: the frozen tower comes from its own checkpoint
    import torch

    state = torch.load(out / WEIGHTS_NAME, weights_only=True)
    assert set(state) == {"head.weight", "head.bias", "classifier.weight", "classifier.bias"}


def test_train_encoder_verb_on_runs_named_by_nothing_but_their_labels(tmp_path: Path) -> None:
    data, labels = write_labelled_runs(tmp_path / "runs", runs=6, length=4)
    out = tmp_path / "encoder"
    args = ["train-encoder", str(data), "--labels", str(labels), "--out", str(out), "--image-size", "24"]
    result = runner.invoke(app, [*args, "--epochs", "1", "--threads", "1"])
    assert result.exit_code == 0, result.output
    record = json.loads((out / CONFIG_NAME).read_text())
    assert record["training"]["recipe"]["labels"] == str(labels.resolve())
    assert record["training"]["skipped_unlabelled"] == [] and record["training"]["trajectories"] >= 1


@pytest.mark.parametrize(
    ("field", "value", "said"),
    [
        (
            "normalize",
            {"mean": [0.5, 0.5, 0.5], "std": [float("nan"), 0.25, 0.25]},
            "normalize.std must be three positive",
        ),
        ("normalize", {"mean": [0.5, 0.5], "std": [0.25, 0.25, 0.25]}, "normalize.mean must be three finite"),
        ("input_size", 10**6, "input_size must be a whole number of pixels from 16 to 1024"),
        ("input_size", -5, "input_size must be a whole number of pixels"),
        ("embedding_dim", 7, "embedding_dim 7 is not the network's: its last layer has 256 channels"),
        (
            "architecture",
            {"kind": "cnn", "widths": [32, 10**7], "neck": "batchnorm"},
            "architecture.widths must be",
        ),
    ],
)
def test_a_crafted_encoder_config_is_one_clear_error(
    trained: tuple[Path, Path, Path], tmp_path: Path, field: str, value: object, said: str
) -> None:
    """Issue 45 items 3 and 6: an edited `encoder.json` never reaches torch (a 175 TiB allocation, NaN
    embeddings in the shared cache): the value is named."""
    _, first, _ = trained
    crafted = Path(shutil.copytree(first, tmp_path / "crafted"))
    config = json.loads((crafted / CONFIG_NAME).read_text())
    config[field] = value
    (crafted / CONFIG_NAME).write_text(json.dumps(config))
    with pytest.raises(EncoderError, match=said):
        load_encoder(f"trained:{crafted}")


def test_the_identity_covers_the_normalisation(trained: tuple[Path, Path, Path], tmp_path: Path) -> None:
    """Another normalisation gives other embeddings: another identity, so another cache key and a memory
    built with one refuses the other."""
    _, first, _ = trained
    edited = Path(shutil.copytree(first, tmp_path / "edited"))
    config = json.loads((edited / CONFIG_NAME).read_text())
    config["normalize"]["std"] = [0.3, 0.3, 0.3]
    (edited / CONFIG_NAME).write_text(json.dumps(config))
    assert load_encoder(f"trained:{edited}").identity != load_encoder(f"trained:{first}").identity
