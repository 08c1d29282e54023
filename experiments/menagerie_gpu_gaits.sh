#!/usr/bin/env bash
# GPU gaits for the two Menagerie robots (issue 31): a robust search warm-started from the CPU
# gait (experiments/menagerie_cpu_gaits.sh), finalists chosen on the selection stream, then the
# chosen gait replayed in randomised worlds of the TEST stream (nothing chose on them).
# Needs eaco on PATH with MJX (Warp) on a GPU (experiments/gpu_session.sh).
#
#   bash experiments/menagerie_gpu_gaits.sh ROBOT SEED OUT [SEARCH_SECONDS] [TRIALS]
#
# search: 512 ants x 16 worlds (CVaR of the worst 4), 6 s horizon, --max-seconds SEARCH_SECONDS
# [200] (compile excluded); 16 finalists x 256 selection worlds; test: TRIALS [2048] worlds of
# 20 s on Warp and 1,024 on MJX-JAX.
set -uo pipefail
robot=$1 seed=$2 out=$3 secs=${4:-200} trials=${5:-2048}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
log() { echo "[$(date -u +%H:%M:%S)] $*" | tee -a "$out/log.txt"; }
log "search $robot seed $seed"
timeout $((secs + 240)) eaco gait --robot "$robot" --backend mjx --impl warp --ants 512 \
  --robust 16 --horizon 6 --max-seconds "$secs" --seed "$seed" \
  --init "$here/results/${robot}_cpu_gait.json" --finalists 16 --select-worlds 256 \
  --no-video --quiet --out "$out/search" >> "$out/log.txt" 2>&1
log "search rc $?"
gait=$out/search/best_gait.json
log "nominal 20 s"
eaco gait-eval "$gait" --backend native --horizon 20 --json 2>>"$out/log.txt" | tail -1 \
  > "$out/${robot}_gpu_gait_eval_20s.json"
log "test stream warp"
timeout 150 eaco gait-eval "$gait" --backend mjx --impl warp --horizon 20 --trials "$trials" \
  --stream test --json 2>>"$out/log.txt" | tail -1 > "$out/${robot}_gpu_gait_test_warp.json"
log "test stream jax"
timeout 150 eaco gait-eval "$gait" --backend mjx --impl jax --horizon 20 --trials 1024 \
  --stream test --json 2>>"$out/log.txt" | tail -1 > "$out/${robot}_gpu_gait_test_jax.json"
log "done"
