"""robomimic/LIBERO and ALOHA episode files written with h5py, in the layouts those projects document."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import h5py
import numpy as np

Frames = Callable[[int, int, int], np.ndarray]  # (episode, camera, t) -> (H, W, 3) uint8


def robomimic_actions(demo: int, length: int) -> np.ndarray:
    """The `actions` the writer stores for a demo: (length, 7), a ramp per dimension."""
    return np.arange(length)[:, None] * 0.1 + np.arange(7)[None] + demo


def robomimic_eef(demo: int, length: int) -> np.ndarray:
    """The `obs/robot0_eef_pos` the writer stores for a demo: (length, 3)."""
    return np.stack([np.arange(length) * 0.01, np.full(length, demo), np.full(length, 0.5)], axis=1)


def aloha_joints(episode: int, length: int) -> np.ndarray:
    """The `qpos` the writer stores for an episode (its `action` is this plus one): (length, 14)."""
    return np.arange(length)[:, None] * 0.01 + np.arange(14)[None] + 100 * episode


def write_robomimic(
    path: Path,
    frames: Frames,
    *,
    demos: int,
    length: int,
    cameras: Sequence[str] = ("agentview_image", "robot0_eye_in_hand_image"),
    masks: dict[str, Sequence[int]] | None = None,
    env_name: str = "Lift",
    instruction: str | None = None,
    opengl: bool = False,
) -> Path:
    """robomimic's `data/demo_<i>/{obs/<cam>, actions, dones, rewards, states}` and `mask/<split>` (LIBERO:
    `problem_info` with the language instruction; `opengl`: LIBERO's `macros_image_convention`, the
    rendered frames stored bottom row first, as robosuite's OpenGL renderer gives them)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as handle:
        data = handle.create_group("data")
        if opengl:
            data.attrs["macros_image_convention"] = "opengl"
        data.attrs["total"] = demos * length
        data.attrs["env_args"] = json.dumps(
            {
                "env_name": env_name,
                "type": 1,
                "env_kwargs": {"control_freq": 20, "camera_names": list(cameras)},
            }
        )
        if instruction is not None:
            data.attrs["problem_info"] = json.dumps(
                {"problem_name": "libero_tabletop_manipulation", "language_instruction": instruction}
            )
        for demo in range(demos):
            group = data.create_group(f"demo_{demo}")
            group.attrs["num_samples"] = length
            group.create_dataset("actions", data=robomimic_actions(demo, length))
            group.create_dataset("dones", data=np.eye(1, length, length - 1, dtype=np.int64)[0])
            group.create_dataset("rewards", data=np.zeros(length))
            group.create_dataset("states", data=np.zeros((length, 32)))
            obs = group.create_group("obs")
            for c, camera in enumerate(cameras):
                stack = np.stack([frames(demo, c, t) for t in range(length)])
                if opengl:
                    stack = stack[:, ::-1]
                if stack.size:
                    obs.create_dataset(camera, data=stack, chunks=(1, *stack.shape[1:]), compression="gzip")
                else:  # frames of zero height or width: HDF5 chunks only positive sizes
                    obs.create_dataset(camera, data=stack)
            obs.create_dataset("robot0_eef_pos", data=robomimic_eef(demo, length))
        if masks:
            group = handle.create_group("mask")
            for split, members in masks.items():
                group.create_dataset(split, data=np.array([f"demo_{i}".encode() for i in members], dtype="S"))
    return path


def write_aloha(
    folder: Path,
    frames: Frames,
    *,
    episodes: int,
    length: int,
    cameras: Sequence[str] = ("cam_high", "cam_left_wrist"),
    compress: bool = False,
) -> Path:
    """ACT/ALOHA's `record_episodes.py`: `/observations/images/<cam>` raw or JPEG rows, qpos, qvel, action.

    Compressed as upstream does it: `cv2.imencode('.jpg', image)` on the camera's RGB array as it is
    (so the JPEG holds RGB bytes where OpenCV expects BGR; ACT's `cv2.imdecode(row, 1)` gives RGB back).
    """
    folder.mkdir(parents=True, exist_ok=True)
    for episode in range(episodes):
        images = {cam: [frames(episode, c, t) for t in range(length)] for c, cam in enumerate(cameras)}
        with h5py.File(folder / f"episode_{episode}.hdf5", "w", rdcc_nbytes=1024**2 * 2) as root:
            root.attrs["sim"] = False
            root.attrs["compress"] = compress
            obs = root.create_group("observations")
            group = obs.create_group("images")
            lengths = np.zeros((len(cameras), length))
            for c, cam in enumerate(cameras):
                if compress:
                    encoded = [
                        cv2.imencode(".jpg", image, [int(cv2.IMWRITE_JPEG_QUALITY), 90])[1].ravel()
                        for image in images[cam]
                    ]
                    padded = max(len(row) for row in encoded) + 16
                    rows = np.zeros((length, padded), np.uint8)
                    for t, row in enumerate(encoded):
                        rows[t, : len(row)] = row
                        lengths[c, t] = len(row)
                    group.create_dataset(cam, data=rows, dtype="uint8", chunks=(1, padded))
                else:
                    stack = np.stack(images[cam])
                    chunks = (1, *stack.shape[1:]) if stack.size else None  # HDF5 chunks only positive sizes
                    group.create_dataset(cam, data=stack, dtype="uint8", chunks=chunks)
            obs.create_dataset("qpos", data=aloha_joints(episode, length))
            obs.create_dataset("qvel", data=np.zeros((length, 14)))
            root.create_dataset("action", data=aloha_joints(episode, length) + 1)
            if compress:
                root.create_dataset("compress_len", data=lengths)
    return folder


def write_maniskill3(
    folder: Path,
    frames: Frames,
    *,
    episodes: int,
    steps: int,
    success: Sequence[bool],
    name: str = "trajectory",
) -> Path:
    """ManiSkill3's `RecordEpisode` output as version 3.0.1 writes it (checked against a real PickCube-v1
    recording): `<name>.h5` with `traj_<i>/obs/{agent,extra,sensor_data,sensor_param}`, `actions`,
    `env_states`, per-step `success`/`rewards`, and `<name>.json` with `env_info` and `episodes`."""
    folder.mkdir(parents=True, exist_ok=True)
    with h5py.File(folder / f"{name}.h5", "w") as handle:
        for episode in range(episodes):
            group = handle.create_group(f"traj_{episode}")
            obs = group.create_group("obs")
            obs.create_dataset("agent/qpos", data=maniskill3_qpos(episode, steps + 1))
            obs.create_dataset("agent/qvel", data=np.zeros((steps + 1, 9), np.float32))
            obs.create_dataset(
                "extra/tcp_pose",
                data=np.tile([0.1, 0.0, 0.2, 1.0, 0.0, 0.0, 0.0], (steps + 1, 1)).astype(np.float32),
            )
            obs.create_dataset(
                "extra/goal_pos", data=np.tile([0.05, 0.05, 0.1], (steps + 1, 1)).astype(np.float32)
            )
            obs.create_dataset("extra/is_grasped", data=np.arange(steps + 1) > steps // 2)
            rgb = np.stack([frames(episode, 0, t) for t in range(steps + 1)])
            obs.create_dataset("sensor_data/base_camera/rgb", data=rgb)
            obs.create_dataset(
                "sensor_param/base_camera/intrinsic_cv", data=np.zeros((steps + 1, 3, 3), np.float32)
            )
            group.create_dataset("actions", data=maniskill3_actions(episode, steps))
            group.create_dataset("env_states/actors/cube", data=np.zeros((steps + 1, 13), np.float32))
            group.create_dataset("success", data=np.full(steps, success[episode]))
            group.create_dataset("rewards", data=np.zeros(steps, np.float32))
    meta = {
        "env_info": {"env_id": "PickCube-v1", "env_kwargs": {"obs_mode": "rgb"}, "max_episode_steps": 50},
        "commit_info": None,
        "episodes": [
            {"episode_id": e, "episode_seed": e, "control_mode": "pd_joint_pos", "elapsed_steps": steps,
             "reset_kwargs": {"options": None, "seed": e}, "success": bool(success[e])}
            for e in range(episodes)
        ],
    }  # fmt: skip
    (folder / f"{name}.json").write_text(json.dumps(meta, indent=1))
    return folder / f"{name}.h5"


def maniskill3_qpos(episode: int, rows: int) -> np.ndarray:
    return (np.arange(rows)[:, None] * 0.01 + np.arange(9)[None] + episode).astype(np.float32)


def maniskill3_actions(episode: int, steps: int) -> np.ndarray:
    return (np.arange(steps)[:, None] + 0.5 * np.arange(8)[None] + 10 * episode).astype(np.float32)
