#!/bin/bash
# Session 27 device script, prepared in session 26 (issue 30). Usage: bash out/gpu_s27.sh PHASE STOP_S [ARGS]
# The tracked tree is 54 MB of the 64 MiB a call may carry. Before the first call, take the route
# walker's results out of the index for the GPU phase (they stay on disk; the command needs none):
#   git rm -r -q --cached 'experiments/results/walk*'; echo '/experiments/results/walk*' >> .git/info/exclude
# and afterwards undo it: git reset -q -- 'experiments/results/walk*' (and drop the exclude line).
# Calls, chained at once (the machine goes back after 30 s idle):
# (measured in session 26: the tree without walk* is 25 MiB; the tool counts disk blocks)
#   1 carry [out/gpu_s27.sh, .wx, .wp, .w/p0]:          bash out/gpu_s27.sh part 0 0
#   2 carry [out/gpu_s27.sh, .w/p1, .w/p2, .w/p3]:      bash out/gpu_s27.sh part 0 1 2 3
#   3 carry [out/gpu_s27.sh, .w/p4, .w/p5, .w/p6]:      bash out/gpu_s27.sh part 0 4 5 6 && bash out/gpu_s27.sh r32 570
#   4 carry [out/gpu_s27.sh]: bash out/gpu_s27.sh fronts 580 endurance; 5: the same with cot
#  part N...: warp-lang's xz tarball (.w/pN, split -b 12000000 of warp 1.19.0 stripped as in
#          ../shared/tools/warp-parts.sh, xz -9e; sha256 prefix 4f4525026292d340) and, on the
#          first call, the MuJoCo wheels (.wx) and pymoo's (.wp).
#  r32:    the stored flat gait flat_r32: 4096 test-stream worlds on Warp and on MJX-JAX, then
#          1024 ten-minute walks on Warp.
#  search NAME SEED FLAGS...: a constrained search from flat_r32 ($INIT, $ROBUST=32, $ANTS=128,
#          $SECS=200, $MARGIN=0.1), e.g. toward 0.35 m/s: ANTS=256 SECS=300 ... search nao_flat_fast 11 --steer
#  fronts SECOND: experiments/gait_fronts.py, MuJoCo Warp, heading feedback, around flat_r32,
#          128 ants x 4 worlds x 16 generations, 20 s, seeds 0-9 (both arms, equal evaluations;
#          NSGA-II evaluates one seed per call, an estimated 300 s of the call: check the first).
T0=$(date +%s); R=$(pwd); P=$1; STOP=${2:-560}; shift 2
left() { echo $(( STOP - ( $(date +%s) - T0 ) )); }
if [ ! -d /tmp/eaco/eaco_jax ]; then
  mkdir -p /tmp/src/experiments/results/tsp_large /tmp/site /tmp/eaco && cp -r eaco_jax pyproject.toml README.md robots /tmp/src/ && cp experiments/*.py experiments/*.sh experiments/claims.toml /tmp/src/experiments/ && cp -r experiments/results/tsp_large/lkh /tmp/src/experiments/results/tsp_large/ || exit 1
  if [ -f .wx/whl.tar.xz ]; then mkdir -p /tmp/wx && tar -xJf .wx/whl.tar.xz -C /tmp/wx && cp -r /tmp/wx/site/. /tmp/site/ || exit 1; fi
  if [ -d .wp ]; then python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .wp/*.whl || exit 1; fi
  (cd /tmp/src && python3 -m pip install -q --no-index --no-deps --no-build-isolation --target /tmp/eaco . 2>/dev/null) || exit 1
  echo "setup after $(( $(date +%s) - T0 )) s"
fi
if [ "$P" = part ]; then
  mkdir -p /tmp/wparts && for n in "$@"; do cp .w/p$n /tmp/wparts/ || exit 1; done; ls /tmp/wparts | tr '\n' ' '
  if [ $(ls /tmp/wparts | wc -l) = 7 ]; then
    cat /tmp/wparts/p0 /tmp/wparts/p1 /tmp/wparts/p2 /tmp/wparts/p3 /tmp/wparts/p4 /tmp/wparts/p5 /tmp/wparts/p6 | sha256sum | cut -c1-16
    cat /tmp/wparts/p0 /tmp/wparts/p1 /tmp/wparts/p2 /tmp/wparts/p3 /tmp/wparts/p4 /tmp/wparts/p5 /tmp/wparts/p6 | xz -d | tar -x -C /tmp/site && echo "warp unpacked"
  fi
  exit 0
fi
cd /tmp
export PYTHONPATH=/tmp/eaco:/tmp/site MUJOCO_GL=disable JAX_PLATFORMS=cuda,cpu PATH=/tmp/eaco/bin:$PATH PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
python3 -c "import jax, jaxlib, numpy, mujoco; print('jax', jax.__version__, 'jaxlib', jaxlib.__version__, 'numpy', numpy.__version__, 'mujoco', mujoco.__version__)"
IMPL=jax; python3 -c "import warp; print('warp', warp.__version__)" 2>/dev/null && IMPL=warp
mkdir -p /tmp/rep
save() { cp $R/out/gpu_s27.sh /tmp/rep/; tar czf $OUT/s27.tgz -C /tmp/rep .; }
F=$R/experiments/results/nao_constrained_warp/flat_r32/best_gait.json
if [ "$P" = r32 ]; then
  for impl in warp jax; do
    timeout $(( $(left) - 20 )) eaco gait-eval $F --backend mjx --impl $impl --trials 4096 --json > /tmp/rep/r32_test4096_$impl.json 2> /tmp/rep/r32_test4096_$impl.err
    echo "r32 test $impl rc $? after $(( $(date +%s) - T0 )) s"; tail -c 300 /tmp/rep/r32_test4096_$impl.err; save
  done
  timeout $(( $(left) - 15 )) eaco gait-eval $F --backend mjx --impl $IMPL --horizon 600 --trials 1024 --out /tmp/rep/r32_thermal1024_$IMPL --no-video --json > /tmp/rep/r32_thermal1024_$IMPL.json 2> /tmp/rep/r32_thermal1024_$IMPL.err
  echo "r32 thermal $IMPL rc $? after $(( $(date +%s) - T0 )) s"; tail -c 600 /tmp/rep/r32_thermal1024_$IMPL.err; save
fi
if [ "$P" = fronts ]; then
  (cd /tmp/src/experiments && timeout $(( $(left) - 10 )) python3 gait_fronts.py --second $1 --backend mjx --impl $IMPL --horizon 20 --worlds 4 --ants 128 --generations 16 --seeds 0-9 --steer --target-noise 0.000443 --init $F --out /tmp/rep/fronts_$1.json > /tmp/rep/fronts_$1.log 2>&1)
  echo "fronts $1 rc $? after $(( $(date +%s) - T0 )) s; overflow lines: $(grep -c overflow /tmp/rep/fronts_$1.log)"; grep -v -e overflow -e "To disable" /tmp/rep/fronts_$1.log | tail -c 1500; save
fi
if [ "$P" = search ]; then  # search NAME SEED FLAGS...: from flat_r32 (or $INIT), $ROBUST worlds, $ANTS ants, $SECS s
  N=$1; S=$2; shift 2
  timeout $(( $(left) - 10 )) eaco gait --constrained --constraint-method deb --constraint-margin ${MARGIN:-0.1} --robust ${ROBUST:-32} --ants ${ANTS:-128} --horizon 20 --max-seconds ${SECS:-200} \
    --init ${INIT:-$F} --backend mjx --impl $IMPL --finalists 16 --select-worlds 64 --trials 1024 --target-noise 0.000443 --seed $S "$@" \
    --out /tmp/rep/$N --no-video --json > /tmp/rep/$N.log 2> /tmp/rep/$N.err
  echo "search $N rc $? after $(( $(date +%s) - T0 )) s"; tail -c 1200 /tmp/rep/$N.err; save
fi
if [ "$P" = eval ]; then  # eval GAIT_FILE IMPL...: 4096 test-stream worlds of the record's seed
  G=$1; shift
  for impl in "$@"; do
    timeout $(( $(left) - 10 )) eaco gait-eval $R/$G --backend mjx --impl $impl --trials 4096 --json > /tmp/rep/eval_$impl.json 2> /tmp/rep/eval_$impl.err
    echo "eval $impl rc $? after $(( $(date +%s) - T0 )) s"; tail -c 300 /tmp/rep/eval_$impl.err; save
  done
fi
