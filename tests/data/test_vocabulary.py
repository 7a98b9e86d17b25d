"""Your own failure words: outcome-only labels, free-text descriptions and a vocabulary file."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from lerobot_writer import write_lerobot_v3
from rrd import rows
from synthetic import write_aha_dataset
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from rfr_viz.paths import REPLAY
from robofailring import FailureMemory, ground
from robofailring.data.grounding import UNTYPED_SENTENCE, Vocabulary, failure_type
from robofailring.data.vocabulary import read_vocabulary
from robofailring.errors import SymbolError, VocabularyError

runner = CliRunner()
KNOCKED = "the gripper knocking the cup over"


def _run(*args: object) -> str:
    result = runner.invoke(app, [str(arg) for arg in args])
    assert result.exit_code == 0, result.output
    return result.stdout


def test_a_vocabulary_grounds_its_own_symbols_and_stages_and_refuses_bad_entries(tmp_path: Path) -> None:
    words = tmp_path / "words.yaml"
    words.write_text(f"symbols:\n  Knocked_Cup: {KNOCKED}.\nstages:\n  2: drawer-opening stage\n")
    vocabulary = read_vocabulary(words)
    assert vocabulary == Vocabulary(symbols={"knocked_cup": KNOCKED}, stages={2: "drawer-opening stage"})
    assert (
        ground("knocked_cup_wp2", vocabulary)
        == f"The failure was caused by {KNOCKED} at the drawer-opening stage"
    )
    assert ground("slip_wp2", vocabulary).endswith(
        "object slippage from the gripper at the drawer-opening stage"
    )
    assert ground("failure") == UNTYPED_SENTENCE and failure_type("knocked_cup", vocabulary) == "knocked_cup"
    with pytest.raises(SymbolError, match=r"unknown failure token 'knocked'.*--vocabulary"):
        ground("knocked_cup_wp2")  # without the vocabulary it is still a named error
    for text, fault in [
        ('{"symbols": {"a": "x", "A": "y"}}', "defined twice"),
        ('{"symbols": {"a": "x", "a": "y"}}', "defined twice"),
        ('{"symbols": {"a": ""}}', "empty sentence"),
        ('{"symbols": {"slip": "mine"}}', "already a Table 5 symbol"),
        ('{"symbols": {"a b": "x"}}', "lower-case words"),
        ('{"symbols": {}}', "defines no symbol"),
        ('{"words": {}}', "must be an object with 'symbols'"),
    ]:
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(VocabularyError, match=fault):
            read_vocabulary(bad)


def test_a_symbol_beginning_with_a_table_5_word_grounds_as_the_vocabulary_says(tmp_path: Path) -> None:
    words = tmp_path / "words.yaml"
    words.write_text(
        "symbols:\n  slip_twice: the cup slipping twice\n  slip_episode: a slip seen on replay\n"
    )
    vocabulary = read_vocabulary(words)
    stage = "at the interaction / grasping stage (Waypoint 2)"
    assert ground("slip_twice_wp2", vocabulary) == f"The failure was caused by the cup slipping twice {stage}"
    assert ground("slip_episode_wp2_episode4", vocabulary) == (
        f"The failure was caused by a slip seen on replay {stage}"
    )
    assert failure_type("slip_twice_wp2", vocabulary) == "slip_twice"
    assert (
        ground("slip_wp2", vocabulary)
        == f"The failure was caused by object slippage from the gripper {stage}"
    )
    assert ground("episode3_slip_wp2_episode3", vocabulary) == ground("slip_wp2")
    with pytest.raises(SymbolError, match=r"unknown stage token 'twice'.*--vocabulary FILE"):
        ground("slip_twice_wp2")  # without the vocabulary, Table 5's `slip` and a word it does not know


def test_outcome_only_labels_with_descriptions_build_detect_and_replay_on_lerobot(tmp_path: Path) -> None:
    data = write_lerobot_v3(tmp_path / "so101", lengths=(8, 7, 9), tasks=("pick up the cube",) * 3)
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "episode_index,outcome,symbol,description\n"
        "0,failure,,knocked the cup over\n"
        "1,success,,\n"
        "2,failure,,\n"
    )
    cache = ["--cache-dir", tmp_path / "cache"]
    memory = tmp_path / "memory"
    _run("build-memory", data, "--out", memory, "--labels", labels, *cache)
    built = FailureMemory.load(memory)
    sentences = {e.episode: (e.symbol, e.description) for e in built.entries}
    assert sentences == {
        "episode_0": ("failure", "knocked the cup over"),
        "episode_2": ("failure", UNTYPED_SENTENCE),
    }
    found = json.loads(
        _run(
            "detect",
            data,
            "--memory",
            memory,
            "--trajectory",
            "episode_0",
            "--delta",
            "0.5",
            "--json",
            *cache,
        )
    )
    assert found["report"]["neighbors"][0]["description"] == "knocked the cup over"
    out = tmp_path / "recordings"
    _run(
        "replay",
        data,
        "--memory",
        memory,
        "--trajectory",
        "episode_0",
        "--delta",
        "0.5",
        "--out",
        out,
        *cache,
    )
    (recording,) = out.glob("*.rrd")
    text = rows(recording, REPLAY.report, "TextDocument:text")[-1][1][0]
    assert "| `failure` | knocked the cup over |" in text  # the report's table of nearest entries


def test_a_memory_keeps_its_vocabulary_and_grounds_the_same_when_copied(tmp_path: Path) -> None:
    data = write_aha_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3
    )
    words = tmp_path / "words.json"
    words.write_text(json.dumps({"symbols": {"knocked_cup": KNOCKED}, "stages": {"2": "reach for the cup"}}))
    labels = tmp_path / "labels.json"
    labels.write_text(
        json.dumps(
            [{"episode": "pick_cube_grasp_wp2_episode0", "outcome": "failure", "symbol": "knocked_cup_wp2"}]
        )
    )
    cache = ["--cache-dir", tmp_path / "cache"]
    memory = tmp_path / "memory"
    refused = runner.invoke(app, ["build-memory", str(data), "--out", str(memory), "--labels", str(labels)])
    assert (
        refused.exit_code == 2 and "unknown failure token 'knocked'" in refused.output and not memory.exists()
    )
    _run("build-memory", data, "--out", memory, "--labels", labels, "--vocabulary", words, *cache)
    assert json.loads((memory / "manifest.json").read_text())["vocabulary"] == "vocabulary.json"
    sentence = f"The failure was caused by {KNOCKED} at the reach for the cup"
    copied = tmp_path / "elsewhere" / "memory"
    shutil.copytree(memory, copied)
    words.unlink()  # the copy needs nothing outside its folder
    for folder in (memory, copied):
        loaded = FailureMemory.load(folder)
        assert {e.description for e in loaded.entries if e.symbol == "knocked_cup_wp2"} == {sentence}
    episode = data / "pick_cube_grasp_wp2_episode0"
    found = json.loads(_run("detect", episode, "--memory", copied, "--delta", "0.5", "--json", *cache))
    assert found["report"]["neighbors"][0]["description"] in {sentence, ground("grasp_wp2")}
    assert sentence in {n["description"] for n in found["report"]["neighbors"]}

    # the copy grows with the dataset's own symbol and no --vocabulary: it grounds with the one it keeps
    more = write_aha_dataset(
        tmp_path / "more", tasks=("pick_cube",), symbols=("slip_wp3",), episodes=1, length=3
    )
    more_labels = tmp_path / "more.json"
    more_labels.write_text(
        json.dumps(
            [{"episode": "pick_cube_slip_wp3_episode0", "outcome": "failure", "symbol": "knocked_cup_wp2"}]
        )
    )
    _run("build-memory", more, "--labels", more_labels, "--add-to", copied, *cache)
    grown = FailureMemory.load(copied)
    assert {e.description for e in grown.entries if e.episode == "pick_cube_slip_wp3_episode0"} == {sentence}
    assert (
        grown.vocabulary == FailureMemory.load(memory).vocabulary and (copied / "vocabulary.json").is_file()
    )


def test_episode_folders_named_with_a_vocabulary_symbol_starting_with_a_table_5_word(tmp_path: Path) -> None:
    """Issue 50: `pick_cube_slip_twice_wp3_episode0` is the vocabulary's `slip_twice` (not Table 5's `slip`
    and an unknown `twice`), in a dataset's folder names as in its labels, for build-memory and detect."""
    data = write_aha_dataset(
        tmp_path / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2", "slip_twice_wp3", "knocked_cup_wp2"),
        episodes=2,
        length=4,
    )
    words = tmp_path / "words.yaml"
    words.write_text(f"symbols:\n  slip_twice: the cup slipping twice\n  knocked_cup: {KNOCKED}\n")
    memory, cache = tmp_path / "memory", ["--cache-dir", tmp_path / "cache"]
    built = runner.invoke(
        app, [str(a) for a in ("build-memory", data, "--out", memory, "--vocabulary", words)]
    )
    assert built.exit_code == 0, built.output  # every folder read: none skipped for an unknown 'twice'
    entries = FailureMemory.load(memory).entries
    assert {entry.symbol for entry in entries} == {"grasp_wp2", "slip_twice_wp3", "knocked_cup_wp2"}
    (sentence,) = {entry.description for entry in entries if entry.symbol == "slip_twice_wp3"}
    assert (
        sentence
        == "The failure was caused by the cup slipping twice at the manipulation / movement stage (Waypoint 3)"
    )
    episode = data / "pick_cube_slip_twice_wp3_episode1"
    found = runner.invoke(app, [str(a) for a in ("detect", episode, "--memory", memory, "--json", *cache)])
    assert found.exit_code == 0, found.output  # the memory's vocabulary reads the folder's name
    assert json.loads(found.stdout)["task"] == "pick_cube"
    unknown = runner.invoke(app, [str(a) for a in ("build-memory", data, "--out", tmp_path / "m2", *cache)])
    assert unknown.exit_code == 3  # without the vocabulary: listed, with the way to name them
    assert "unknown failure type 'twice'" in unknown.output and "pass --vocabulary FILE" in unknown.output
