#!/bin/bash
# Session 26 device script (issues 30, 33). Usage: bash out/gpu_s26.sh PHASE STOP_S [ARGS]
#  setup:  eaco_jax + the MuJoCo wheels (.wx carried).
#  part N...: warp-lang's xz tarball arrives in 7 parts (.w/pN carried, one per call: the tree is
#          52 MiB of the 64 MiB a call may carry); after the last one it is unpacked.
#  final:  the margin gait on MJX-Warp: 4096 test-stream worlds, then 1024 ten-minute walks.
#  tsp:    #33's pr2392 30 s row with today's code (10 seeds, 100-109).
#  search NAME SEED FLAGS...: a constrained margin search from the margin gait (or $INIT;
#          $ROBUST worlds per ant, $ANTS ants, $SECS s).
# Results in /tmp/rep, tarred into $OUT/s26.tgz after every step.
T0=$(date +%s); R=$(pwd); P=$1; STOP=${2:-560}; shift 2
left() { echo $(( STOP - ( $(date +%s) - T0 ) )); }
if [ ! -d /tmp/eaco/eaco_jax ]; then
  mkdir -p /tmp/src/experiments/results/tsp_large /tmp/site /tmp/eaco && cp -r eaco_jax pyproject.toml README.md robots /tmp/src/ && cp experiments/*.py experiments/*.sh experiments/claims.toml /tmp/src/experiments/ && cp -r experiments/results/tsp_large/lkh /tmp/src/experiments/results/tsp_large/ || exit 1
  if [ -f .wx/whl.tar.xz ]; then mkdir -p /tmp/wx && tar -xJf .wx/whl.tar.xz -C /tmp/wx && cp -r /tmp/wx/site/. /tmp/site/ || exit 1; fi
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
save() { cp $R/out/gpu_s26.sh /tmp/rep/; tar czf $OUT/s26.tgz -C /tmp/rep .; }
B=$R/experiments/results/nao_steer_margin_gpu/best_gait.json
if [ "$P" = final ]; then
  timeout $(( $(left) - 20 )) eaco gait-eval $B --backend mjx --impl $IMPL --trials 4096 --json > /tmp/rep/test4096_$IMPL.json 2> /tmp/rep/test4096_$IMPL.err
  echo "test $IMPL rc $? after $(( $(date +%s) - T0 )) s"; tail -c 400 /tmp/rep/test4096_$IMPL.err; save
  timeout $(( $(left) - 15 )) eaco gait-eval $B --backend mjx --impl $IMPL --horizon 600 --trials 1024 --out /tmp/rep/thermal1024_$IMPL --no-video --json > /tmp/rep/thermal1024_$IMPL.json 2> /tmp/rep/thermal1024_$IMPL.err
  echo "thermal $IMPL rc $? after $(( $(date +%s) - T0 )) s"; tail -c 600 /tmp/rep/thermal1024_$IMPL.err; save
fi
if [ "$P" = tsp ]; then
  python3 /tmp/src/experiments/tsp_time_to_quality.py --local-search or-2opt --preset mmas --instances pr2392 --ants 96 --seeds 10 --first-seed 100 --seconds 30 --checkpoints 1 3 10 30 --out /tmp/rep/reg_pr2392_30s.json > /tmp/rep/reg_pr2392.log 2>&1
  echo "pr2392 rc $? after $(( $(date +%s) - T0 )) s"; tail -c 800 /tmp/rep/reg_pr2392.log; save
fi
if [ "$P" = search ]; then
  N=$1; S=$2; shift 2
  timeout $(( $(left) - 10 )) eaco gait --constrained --constraint-method deb --constraint-margin 0.1 --robust ${ROBUST:-16} --ants ${ANTS:-128} --horizon 20 --max-seconds ${SECS:-150} \
    --init ${INIT:-$B} --backend mjx --impl $IMPL --finalists 16 --select-worlds 64 --trials 1024 --target-noise 0.000443 --seed $S "$@" \
    --out /tmp/rep/$N --no-video --json > /tmp/rep/$N.log 2> /tmp/rep/$N.err
  echo "search $N rc $? after $(( $(date +%s) - T0 )) s"; tail -c 1200 /tmp/rep/$N.err; save
fi
