#!/bin/bash
# Session 31 device script (from gpu_s30.sh as run in session 30), prepared in session 30. Usage: bash out/gpu_s31.sh PHASE STOP_S [ARGS]
# Before the first call, take the route walker's results out of the index (they stay on disk):
#   git rm -r -q --cached 'experiments/results/walk*'; echo '/experiments/results/walk*' >> .git/info/exclude
# and afterwards undo it: git reset -q -- 'experiments/results/walk*' (and drop the exclude line).
# Chain the calls AT ONCE, no thinking between them: the machine goes back after 30 s idle, and a
# fresh one has none of the parts (session 28 lost a machine that way).
#   1 carry [out/gpu_s31.sh, .wx, .wp, .w/p0]:   bash out/gpu_s31.sh part 0 0
#   2 carry [out/gpu_s31.sh, .w/p1, .w/p2, .w/p3]: bash out/gpu_s31.sh part 0 1 2 3
#   3 carry [out/gpu_s31.sh, .w/p4, .w/p5, .w/p6]: bash out/gpu_s31.sh part 0 4 5 6
#   4 carry [out/gpu_s31.sh]: bash out/gpu_s31.sh walks 430 warp   (nao_library with its 3 s start ramp:
#     the archive walker's GPU test, 11 scenes x 100 worlds; session 30's run without the ramp took 276 s)
#   then, for #33, the TSP phases of docs/tsp_large.md (not in this script yet).
#  part N...: warp-lang's xz tarball in seven parts (as gpu_s27.sh), the MuJoCo wheels (.wx) and pymoo's (.wp).
#  warptest: tests/test_warp.py on the GPU (the device's own pytest), from /tmp/t, not the repo root
#          (about 255 s: the Warp/JAX agreement test takes 228 s).
#  overhead: experiments/fronts_overhead.py on Warp at the fronts' scale (4 generations): does the
#          colony arm cost 2x the bare evaluation there (session 27: 201 s against 108 s)? Under
#          MJX's default graph mode (warp) and under warp_staged (EACO_WARP_GRAPH_MODE): the default
#          replays a CUDA graph only for the buffer addresses it captured.
#  walks IMPL: experiments/walk_route.py, --gaits $GAITS (nao_library), 11 test scenes x 100 worlds
#          (MJX-JAX took 505 s for nine of the eleven side by side: give jax two calls).
#  fronts SECOND: experiments/gait_fronts.py as in session 27 (score on $SCORE=4 selection worlds;
#          rescoring costs as much as the search per world: 64 would double the run).
#  library: experiments/gait_library.py --constrained around flat_r32 on Warp, 20 s rollouts,
#          the encoders' noise, 4 worlds, 128 ants x 12 iterations, seeds 0-9, QDax beside
#          (.wq: py3.12 wheels of qdax 0.5.0, scikit-learn, joblib, threadpoolctl, cloudpickle,
#          narwhals, 10 MB; QDax's MAP-Elites path imports flax, optax, chex, brax and scipy, which
#          the device or .wx has; untried on the device). docs/gait_library.md says why a CPU
#          run cannot judge these gaits.
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
save() { cp $R/out/gpu_s31.sh /tmp/rep/; tar czf $OUT/s31.tgz -C /tmp/rep .; }
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
  (cd /tmp/src/experiments && timeout $(( $(left) - 10 )) python3 gait_fronts.py --second $1 --backend mjx --impl $IMPL --horizon 20 --worlds 4 --ants 128 --generations 16 --seeds 0-9 --steer --target-noise 0.000443 --init $F --score-worlds ${SCORE:-4} --out /tmp/rep/fronts_$1.json > /tmp/rep/fronts_$1.log 2>&1)
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

if [ "$P" = kernel ]; then  # #33 item 2: the sparse Pallas kernel compiled on the GPU, against its scan
  mkdir -p /tmp/t && cp $R/tests/test_tsp_sparse.py $R/tests/conftest.py /tmp/t/
  (cd /tmp/t && timeout 150 python3 -m pytest -p no:cacheprovider -q -k kernel test_tsp_sparse.py > /tmp/rep/kernel_test.txt 2>&1)
  echo "kernel test rc $? after $(( $(date +%s) - T0 )) s"; tail -n 4 /tmp/rep/kernel_test.txt
  (cd /tmp/src/experiments && timeout $(( $(left) - 10 )) python3 tsp_sparse_kernel.py --sizes 3000 10000 15112 --ants 96 1536 --caps 0 128 --out /tmp/rep/sparse_kernel_gpu.json > /tmp/rep/sparse_kernel_gpu.log 2>&1)
  echo "kernel bench rc $? after $(( $(date +%s) - T0 )) s"; grep -v -e "To disable" /tmp/rep/sparse_kernel_gpu.log | tail -16; save
fi
if [ "$P" = tspsel ]; then  # #33: the compiled kernel's scan construction against the default moves, 5k selection instance
  TL=/tmp/src/experiments/tsp_large.py
  for a in ${ARMS:-moves kernel}; do
    case $a in kernel) F="--construction kernel --max-new-edges 128 --ants 1536 --merge-ants 96 --ls-focus-width 128";;
      mne64) F="--construction moves --max-new-edges 64 --ants 1536 --merge-ants 96 --ls-focus-width 128";;
      focus256) F="--construction moves --max-new-edges 128 --ants 1536 --merge-ants 96 --ls-focus-width 256";;
      *) F="--ants 1536";; esac
    [ -f /tmp/rep/warm_sel5k_$a.json ] || timeout 60 python3 $TL --sizes 5000 --seconds 12 --instance-seeds 1 --seeds 0 --eaco-args "$F" --process-timeout 50 --work /tmp/tsp5 --out /tmp/rep/warm_sel5k_$a.json > /tmp/rep/warm_sel5k_$a.log 2>&1
    echo "warm $a rc $? after $(( $(date +%s) - T0 )) s"; tail -c 300 /tmp/rep/warm_sel5k_$a.log
    for s in 0 1 2; do
      [ $(left) -lt 50 ] && break
      timeout 75 python3 $TL --sizes 5000 --seconds 30 --instance-seeds 1 --seeds $s --eaco-args "$F" --process-timeout 70 --work /tmp/tsp5 --out /tmp/rep/sel5k_${a}_s$s.json > /tmp/rep/sel5k_${a}_s$s.log 2>&1
      echo "sel5k $a seed $s rc $? after $(( $(date +%s) - T0 )) s: $(grep -o 'over_bhh_percent[^,]*' /tmp/rep/sel5k_${a}_s$s.json | head -1)"
    done
    save
  done
fi
if [ "$P" = tsp10 ]; then  # #33 stretch: colonies above 384 at 10k (selection instance seed 1, 18 s), then REPORT=1: the winner on instance seed 0
  TL=/tmp/src/experiments/tsp_large.py
  if [ -z "$REPORT" ]; then
    for a in ${ARMS:-a384 a768 a1536}; do
      F="--ants ${a#a}"
      [ -f /tmp/rep/warm_sel10k_$a.json ] || timeout 60 python3 $TL --sizes 10000 --seconds 12 --instance-seeds 1 --seeds 0 --eaco-args "$F" --process-timeout 50 --work /tmp/tsp10 --out /tmp/rep/warm_sel10k_$a.json > /tmp/rep/warm_sel10k_$a.log 2>&1
      for s in ${SEEDS:-0 1 2}; do
        [ $(left) -lt 40 ] && break
        [ -n "$SEEDS" ] && mv /tmp/rep/sel10k_${a}_s$s.json /tmp/rep/sel10k_${a}_s${s}_first.json
        timeout 60 python3 $TL --sizes 10000 --seconds 18 --instance-seeds 1 --seeds $s --eaco-args "$F" --process-timeout 50 --work /tmp/tsp10 --out /tmp/rep/sel10k_${a}_s$s.json > /tmp/rep/sel10k_${a}_s$s.log 2>&1
        echo "sel10k $a seed $s rc $? after $(( $(date +%s) - T0 )) s: $(grep -o 'over_bhh_percent[^,]*' /tmp/rep/sel10k_${a}_s$s.json | head -1)"
      done
      save
    done
  else
    F="--ants $REPORT"
    timeout 60 python3 $TL --sizes 10000 --seconds 12 --instance-seeds 0 --seeds 0 --eaco-args "$F" --process-timeout 50 --work /tmp/tsp10r --out /tmp/rep/warm_rep10k.json > /dev/null 2>&1
    for s in 0 1 2 3 4 5 6 7 8 9; do
      [ $(left) -lt 35 ] && break
      timeout 60 python3 $TL --sizes 10000 --seconds 18 --instance-seeds 0 --seeds $s --eaco-args "$F" --process-timeout 50 --work /tmp/tsp10r --out /tmp/rep/rep10k_s$s.json > /tmp/rep/rep10k_s$s.log 2>&1
      echo "rep10k seed $s rc $? after $(( $(date +%s) - T0 )) s: $(grep -o 'gap_percent[^,]*' /tmp/rep/rep10k_s$s.json | head -1)"
    done
    save
  fi
fi
if [ "$P" = warptest ]; then
  mkdir -p /tmp/t && cp $R/tests/test_warp.py $R/tests/conftest.py /tmp/t/
  (cd /tmp/t && PYTHONPATH=/tmp/eaco:/tmp/site timeout $(( $(left) - 5 )) python3 -m pytest -p no:cacheprovider -rs -q test_warp.py > /tmp/rep/warptest.txt 2>&1)
  echo "warptest rc $? after $(( $(date +%s) - T0 )) s"; tail -n 15 /tmp/rep/warptest.txt; save
fi
if [ "$P" = walks ]; then  # walks IMPL
  I=$1; W=/tmp/src/experiments/walk_route.py; mkdir -p /tmp/wlogs_$I
  A="--backend mjx --impl $I --motors spec --gaits ${GAITS:-nao_library}"
  if [ "$I" = warp ]; then
    timeout 200 python3 $W $A --worlds 4 --scenes default --out /tmp/ws_${I}_smoke > /tmp/wlogs_$I/smoke.txt 2>&1
    echo "smoke rc $? after $(( $(date +%s) - T0 )) s"; tail -n 4 /tmp/wlogs_$I/smoke.txt
  fi
  pids=""
  for s in default random:1000 random:1001 random:1002 random:1006 random:1010 random:1012 random:1015 random:1016 random:1017 random:1018; do
    XLA_PYTHON_CLIENT_PREALLOCATE=false timeout $(( $(left) - 15 )) python3 $W $A --worlds 100 --scenes $s --out /tmp/ws_$I/${s/:/_} > /tmp/wlogs_$I/${s/:/_}.txt 2>&1 &
    pids="$pids $!"; sleep 1
  done
  for p in $pids; do wait $p; done
  echo "walks $I done after $(( $(date +%s) - T0 )) s"
  for f in /tmp/wlogs_$I/*.txt; do echo "$(basename $f): $(grep -m1 'worlds succeed' $f) overflow $(grep -c overflow $f)"; done
  tar czf $OUT/walks_$I.tgz -C /tmp ws_$I wlogs_$I; save
fi
mkdir -p /tmp/src/experiments/results/nao_constrained_warp/flat_r32 && cp $F /tmp/src/experiments/results/nao_constrained_warp/flat_r32/
if [ "$P" = overhead ]; then
  for gm in warp warp_staged; do
    (cd /tmp/src/experiments && timeout $(( $(left) - 10 )) python3 fronts_overhead.py --backend mjx --impl warp --ants 128 --worlds 4 --generations 4 --seeds 10 --horizon 20 --graph-mode $gm --out /tmp/rep/overhead_warp_$gm.json > /tmp/rep/overhead_warp_$gm.log 2>&1)
    echo "overhead $gm rc $? after $(( $(date +%s) - T0 )) s"; grep -v -e overflow -e "To disable" /tmp/rep/overhead_warp_$gm.log | tail -3; save
  done
fi
if [ "$P" = library ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/qdsite $R/.wq/*.whl || exit 1
  (cd /tmp/src/experiments && PYTHONPATH=$PYTHONPATH:/tmp/qdsite timeout $(( $(left) - 10 )) python3 gait_library.py --parts gait --gait-arms ${1:-eaco qdax} --qdax-vmap --track-turn --backend mjx --constrained --init $F --target-noise 0.000443 --horizon 20 --worlds 4 --ants 128 --iterations 12 --test-worlds 16 --validate-chunk 256 --seeds 0-9 --out /tmp/rep/library${1:+_$1} > /tmp/rep/library${1:+_$1}.log 2>&1)
  echo "library rc $? after $(( $(date +%s) - T0 )) s"; grep -v -e overflow -e "To disable" /tmp/rep/library${1:+_$1}.log | tail -12; save
fi
