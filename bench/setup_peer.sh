#!/usr/bin/env bash
# The bench-only ManiSkill3 environment of bench/bench_peer.py, outside the project and its .venv
# (docs/bench_peer.md): a venv with mani-skill 3.0.x and numpy < 2 (mplib 0.1.x, ManiSkill's motion
# planner, crashes with numpy 2), and Mesa 25's lavapipe from bookworm-backports unpacked into a
# folder (SAPIEN needs VK_KHR_external_semaphore_fd, which bookworm's Mesa 22.3 lacks); nothing is
# installed system-wide. Idempotent: a second run checks and changes nothing.
#
#   bash bench/setup_peer.sh [ENV_DIR]     (default: $ROBOFAILRING_PEER_ENV, else ~/.cache/robofailring/peer-env)
#
# PEER_TORCH picks the torch requirement (default: torch from the CPU index when it answers, else
# from the default index); e.g. PEER_TORCH='torch==2.13.0+cpu' for a local CPU wheel.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
env_dir="${1:-${ROBOFAILRING_PEER_ENV:-${XDG_CACHE_HOME:-$HOME/.cache}/robofailring/peer-env}}"
mkdir -p "$env_dir"
env_dir="$(cd "$env_dir" && pwd)"
python="${PYTHON:-python3}"

if [[ ! -x "$env_dir/venv/bin/python" ]]; then
  "$python" -m venv "$env_dir/venv"
fi
pip=("$env_dir/venv/bin/python" -m pip install --quiet --disable-pip-version-check)
if ! "$env_dir/venv/bin/python" -c "import torch" 2>/dev/null; then
  if [[ -n "${PEER_TORCH:-}" ]]; then
    "${pip[@]}" "$PEER_TORCH"
  else
    "${pip[@]}" --index-url https://download.pytorch.org/whl/cpu torch || "${pip[@]}" torch
  fi
fi
"${pip[@]}" -r "$here/requirements-peer.txt"

# Mesa 25 (lavapipe) and the libdrm it needs, from bookworm-backports, with apt's own client but a
# private source list, list cache and archive folder: the system's apt state is left as it was.
mesa="$env_dir/mesa"
if [[ ! -f "$mesa/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so" ]]; then
  apt_dir="$env_dir/apt"
  mkdir -p "$apt_dir/lists/partial" "$apt_dir/cache/archives/partial" "$apt_dir/debs"
  echo "deb http://deb.debian.org/debian bookworm-backports main" >"$apt_dir/sources.list"
  apt_opts=(-o "Dir::Etc::SourceList=$apt_dir/sources.list" -o "Dir::Etc::SourceParts=/nonexistent"
    -o "Dir::State::Lists=$apt_dir/lists" -o "Dir::Cache=$apt_dir/cache" -o "APT::Sandbox::User=$(id -un)")
  apt-get "${apt_opts[@]}" update -qq
  (cd "$apt_dir/debs" && apt-get "${apt_opts[@]}" download \
    mesa-vulkan-drivers/bookworm-backports libdrm2/bookworm-backports libdrm-amdgpu1/bookworm-backports)
  for deb in "$apt_dir"/debs/*.deb; do dpkg -x "$deb" "$mesa"; done
fi
# The ICD file names its driver by an absolute path into the unpacked folder (the packaged one names
# a bare file name, resolved against the system's library path).
sed "s#\"library_path\": \"[^\"]*\"#\"library_path\": \"$mesa/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so\"#" \
  "$mesa/usr/share/vulkan/icd.d/lvp_icd.json" >"$env_dir/lvp_icd.json"
cat >"$env_dir/env.sh" <<EOF
export VK_ICD_FILENAMES="$env_dir/lvp_icd.json"
export LD_LIBRARY_PATH="$mesa/usr/lib/x86_64-linux-gnu\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
EOF
# shellcheck disable=SC1091
source "$env_dir/env.sh"
"$env_dir/venv/bin/python" - <<'EOF'
import gymnasium as gym
import mani_skill
import mani_skill.envs  # noqa: F401
import numpy

assert int(numpy.__version__.split(".")[0]) < 2, f"numpy {numpy.__version__}: mplib 0.1.x needs numpy < 2"
env = gym.make("PickCube-v1", obs_mode="rgb", robot_uids="panda_wristcam", sim_backend="cpu",
               sensor_configs={"width": 32, "height": 32})
env.reset(seed=0)
env.close()
print(f"peer env ready: mani-skill {mani_skill.__version__}, numpy {numpy.__version__}, lavapipe renders")
EOF
touch "$env_dir/ready"
echo "$env_dir"
