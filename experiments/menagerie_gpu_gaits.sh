#!/usr/bin/env bash
# GPU gaits for the two Menagerie robots (issue 31): a robust search warm-started from the CPU
# gait (experiments/menagerie_cpu_gaits.sh), finalists chosen on the selection stream, then the
# chosen gait replayed in randomised worlds of the TEST stream (nothing chose on them).
# Needs eaco on PATH with MJX (Warp) on a GPU (experiments/gpu_session.sh).
#
#   bash experiments/menagerie_gpu_gaits.sh ROBOT SEED OUT [SEARCH_SECONDS] [TRIALS]
#
# search: ANTS [512] x WORLDS [16] (CVaR of the worst quarter), HORIZON [6] s, --max-seconds
# SEARCH_SECONDS [200] (compile excluded), warm start INIT [results/ROBOT_cpu_gait.json];
# 16 finalists x 256 selection worlds; test: TRIALS [2048] worlds of 20 s on Warp and 1,024 on
# MJX-JAX.
set -uo pipefail
robot=$1 seed=$2 out=$3 secs=${4:-200} trials=${5:-2048}
here=$(cd "$(dirname "$0")" && pwd)
ANTS=${ANTS:-512} WORLDS=${WORLDS:-16} HORIZON=${HORIZON:-6}
INIT=${INIT:-$here/results/${robot}_cpu_gait.json}
mkdir -p "$out"
log() { echo "[$(date -u +%H:%M:%S)] $*" | tee -a "$out/log.txt"; }
log "search $robot seed $seed ants $ANTS worlds $WORLDS horizon $HORIZON init $INIT"
timeout $((secs + 240)) eaco gait --robot "$robot" --backend mjx --impl warp --ants "$ANTS" \
  --robust "$WORLDS" --horizon "$HORIZON" --max-seconds "$secs" --seed "$seed" \
  --init "$INIT" --finalists 16 --select-worlds 256 \
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
