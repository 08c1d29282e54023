#!/usr/bin/env bash
# Set up eaco_jax on a CUDA machine that has JAX with CUDA but no network access, from wheels
# carried there (docs/gpu.md: what changes on a GPU). Run from the repository root.
#
# Paths are parameters (environment variables, defaults in brackets):
#   WHEELS  folder of the .whl files to install: mujoco, mujoco-mjx, brax and what they need,
#           built for the machine's Python elsewhere (`pip download` or `pip wheel`) [./wheels]
#   SITE    folder the wheels are installed into                        [$HOME/.eaco/site]
#   EACO    folder this package is installed into                       [$HOME/.eaco/pkg]
#
#   bash experiments/gpu_session.sh install            # the wheels, then this package
#   bash experiments/gpu_session.sh warp PART...       # warp-lang from an xz tarball of its
#                                                      # package folder, split in PARTs (cat)
#   bash experiments/gpu_session.sh check              # versions and devices
#   source experiments/gpu_session.sh env              # then: python experiments/NAME.py ...
#
# pip --no-deps keeps the machine's own CUDA jax; --target folders are put on PYTHONPATH by env.
[[ "${BASH_SOURCE[0]}" == "$0" ]] && set -euo pipefail  # not when sourced: a caller's shell
WHEELS=${WHEELS:-./wheels}
SITE=${SITE:-$HOME/.eaco/site}
EACO=${EACO:-$HOME/.eaco/pkg}

env_vars() {
    # the native MuJoCo backend needs JAX's CPU platform beside the GPU; no display: no video
    export PYTHONPATH=$EACO:$SITE${PYTHONPATH:+:$PYTHONPATH}
    export MUJOCO_GL=${MUJOCO_GL:-disable} JAX_PLATFORMS=${JAX_PLATFORMS:-cuda,cpu}
}

case "${1:-env}" in
install)
    python3 -m pip install -q --no-index --no-deps --no-compile --target "$SITE" "$WHEELS"/*.whl
    rm -rf "$EACO"  # pip --target does not replace an installed copy: a stale one would run
    python3 -m pip install -q --no-index --no-deps --no-build-isolation --target "$EACO" .
    ;;
warp)
    shift
    cat "$@" | xz -d | tar -x -C "$SITE"
    ;;
check)
    env_vars
    python3 -c "import jax, eaco_jax; print('jax', jax.__version__, jax.devices()); \
print('eaco_jax', eaco_jax.__version__)"
    python3 -c "import warp; print('warp', warp.__version__)" 2>/dev/null \
        || echo "warp-lang not installed: --impl jax"
    ;;
env)
    env_vars
    ;;
*)
    echo "usage: bash experiments/gpu_session.sh install|warp PART...|check; source ... env" >&2
    exit 2
    ;;
esac
