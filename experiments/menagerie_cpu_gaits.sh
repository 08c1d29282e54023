#!/usr/bin/env bash
# CPU gaits for the two Menagerie robots (issue 31), small searches on native MuJoCo:
#   stage 1: nominal world (optimisation seed 1), 32 ants x 25 iterations, 4 s horizon;
#   stage 2 (and 3 for the OP3): warm starts (--init: +/-15% of each range) scored by the CVaR
#   over --robust randomised worlds of the optimisation stream of seeds 2 (and 3).
# The last stage is stored as experiments/results/<robot>_cpu_gait.json, replayed 20 s in the
# nominal world and in 256 randomised 4 s worlds of the test stream of its seed (nothing in the
# searches saw or chose on them). About 5 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
export JAX_PLATFORMS=cpu
R=experiments/results
TMP=$(mktemp -d)
eaco() { .venv/bin/eaco "$@"; }
search() {  # robot out seed extra...
  local robot=$1 out=$2 seed=$3; shift 3
  eaco gait --robot "$robot" --ants 32 --horizon 4 --seed "$seed" --backend native --no-video \
    --out "$TMP/$robot-$seed" --quiet "$@" > /dev/null
  cp "$TMP/$robot-$seed/best_gait.json" "$out"
}
search go2 $R/go2_cpu_stage1.json 1 --iterations 25
search go2 $R/go2_cpu_gait.json 2 --iterations 15 --robust 4 --init $R/go2_cpu_stage1.json
search op3 $R/op3_cpu_stage1.json 1 --iterations 25
search op3 $R/op3_cpu_stage2.json 2 --iterations 15 --robust 4 --init $R/op3_cpu_stage1.json
search op3 $R/op3_cpu_gait.json 3 --iterations 12 --robust 8 --init $R/op3_cpu_stage2.json
for robot in go2 op3; do
  eaco gait-eval $R/${robot}_cpu_gait.json --horizon 20 --backend native --json \
    | tail -1 > $R/${robot}_cpu_gait_eval_20s.json
  eaco gait-eval $R/${robot}_cpu_gait.json --horizon 4 --trials 256 --backend native --json \
    | tail -1 > $R/${robot}_cpu_gait_trials.json
done
rm -rf "$TMP"
