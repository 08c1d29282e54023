#!/usr/bin/env bash
# The GPU machine's steps, as they were run for the stored results in results/gpu/.
#
# The bare machine has JAX with CUDA but no mujoco, mujoco-mjx, brax or warp-lang; the wheels
# travel with the working tree (see the device README): `.whl` (py3.12 wheels of mujoco 4.0.0,
# mujoco-core, mujoco-studio, mujoco-mjx 3.17.0, brax 0.14.2, glfw, pyopengl, trimesh) and
# warp-lang in two parts (`.wa/part_a`, `.wb/part_b`, from shared/tools/warp-parts.sh), one per
# call while the machine stays warm.
#
#   bash experiments/gpu_session.sh install      # call 1, carry .whl
#   bash experiments/gpu_session.sh warp-a       # call 2, carry .wa
#   bash experiments/gpu_session.sh warp-b       # call 3, carry .wb
#   source experiments/gpu_session.sh env        # then any experiment below
[[ "${BASH_SOURCE[0]}" == "$0" ]] && set -euo pipefail  # not when sourced: a caller's shell
SITE=/tmp/site
EACO=/tmp/eaco

env_vars() {
    export PYTHONPATH=$EACO:$SITE MUJOCO_GL=disable JAX_PLATFORMS=cuda,cpu
    export WARP_LOG_LEVEL=error PYTHONWARNINGS=ignore
}

case "${1:-env}" in
install)
    python3 -m pip install -q --no-index --no-deps --no-compile --target $SITE .whl/*.whl
    rm -rf $EACO  # pip --target does not replace an installed copy: a stale one would run
    python3 -m pip install -q --no-index --no-deps --no-build-isolation --target $EACO .
    ;;
warp-a)
    mkdir -p /tmp/wparts && cp .wa/part_a /tmp/wparts/
    ;;
warp-b)
    cat /tmp/wparts/part_a .wb/part_b | xz -d | tar -x -C $SITE
    env_vars
    python3 -c "import warp; print('warp', warp.__version__)"
    ;;
env)
    env_vars
    ;;
esac
