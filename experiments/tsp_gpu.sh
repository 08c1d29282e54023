#!/usr/bin/env bash
# Issue 33's large-TSP runs on a CUDA machine that has JAX with CUDA (nothing else needed: the
# TSP uses no MuJoCo). Run from the repository root; results go to $OUT (the device tool's
# output folder) as one .tgz per call, holding r/*.json and r/device.txt (GPU, driver, jax,
# date, commit and the uncommitted changes the call ran with).
#
#   bash experiments/tsp_gpu.sh prof SIZE...            # one iteration of the default colony
#       after WARM (100) warm iterations on each size's selection instance (instance seed 1):
#       tsp_iteration_profile.py; PROFILE_ARGS adds its options (e.g. "--trace"); with
#       BEFORE_DIR (a folder of the repo mirroring eaco_jax/, carried) the same profile runs
#       first on the package with those files laid over it ("before", the same machine)
#   ARMS="a=--acceptance rounds;b=--acceptance unrolled" bash experiments/tsp_gpu.sh arms SIZE...
#       # the profile of each arm (its tsp_iteration_profile.py options), one machine
#   SEEDS="0 1 2" ARMS="label=eaco args;..." bash experiments/tsp_gpu.sh select N SECONDS
#       # selection runs on random instance seed 1 (never reported), one warm-up per arm
#   bash experiments/tsp_gpu.sh rep d15112|N SECONDS "SEEDS" WARM
#       # the report: each seed a fresh `eaco tsp` process on the call clock (tsp_large.py),
#       # on d15112 or the random instance of N cities with instance seed 0; WARM > 0 first
#       # runs one discarded warm-up of WARM seconds that fills the compile caches (d15112 on
#       # d15112 itself, run seed 99: the same programs; N on its seed-1 instance); EARGS
#       # passes eaco options (none: the defaults)
#   bash experiments/tsp_gpu.sh hist N SECONDS [eaco args]
#       # one run on N's selection instance with its per-iteration history kept
#   FLAGS="label=XLA flags;..." bash experiments/tsp_gpu.sh flags N ITERATIONS
#       # each arm's XLA_FLAGS on N's selection instance, ITERATIONS iterations of the default
#       # colony, run seed 0, twice (the first compiles; equal best lengths: the same tours)
#   ENVS="label=VAR=value VAR2=value|eaco options;..." bash experiments/tsp_gpu.sh envs N SECONDS
#       # each arm's environment (and options after a |) on N's selection instance after a
#       # discarded 10 s warm-up of each arm: a call-clock run of SECONDS, run seed 0, twice
#       # per arm (interleaved); the records keep `timing`
#   bash experiments/tsp_gpu.sh diag N SECONDS
#       # where the call's time goes, on N's selection instance after one warm-up: a run
#       # with JAX's compile log and -X importtime, then one under cProfile (slower: its
#       # figures are shares, not times)
#
# The package is installed once per machine into /tmp/site (REFRESH=1 reinstalls it: do so
# after changing the code on a machine that is still warm).
set -u
REPO=$(pwd)
export MUJOCO_GL=disable PYTHONUNBUFFERED=1
SITE=/tmp/site
install_package() {  # DEST [overlay folder]
    rm -rf "$1"
    python3 -m pip install -q --no-deps --no-build-isolation --no-compile --target "$1" "$REPO" \
        > /tmp/pip.log 2>&1 || { tail -20 /tmp/pip.log; exit 1; }
    [ -z "${2:-}" ] || cp -r "$REPO/$2/." "$1/eaco_jax/"
}
if [ ! -d $SITE/eaco_jax ] || [ "${REFRESH:-0}" = 1 ]; then install_package $SITE; fi
export PYTHONPATH=$SITE
cd /tmp  # not the repository root: its source tree would shadow the installed package
W=/tmp/tspw
R=$OUT/r
mkdir -p $R $W
{
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo "no GPU"
    python3 -c "import jax, jaxlib; print(jax.__version__, jaxlib.__version__, jax.devices())"
    date -u
    echo "XLA_FLAGS=${XLA_FLAGS:-}"
    # the code's changes only (results left out of an upload would list as deletions)
    (cd $REPO && git rev-parse HEAD \
        && git status --short --untracked-files=no -- eaco_jax experiments/*.py experiments/*.sh \
        && git diff --stat -- eaco_jax experiments/*.py experiments/*.sh) 2>/dev/null
} > $R/device.txt
profile() {  # OUTFILE SIZES... (options from $PROFILE_ARGS)
    local out=$1; shift
    # shellcheck disable=SC2086
    python3 $REPO/experiments/tsp_iteration_profile.py $(for n in "$@"; do echo --size $n; done) \
        --warm ${WARM:-100} --repeats 5 ${PROFILE_ARGS:-} --work $W --out $out 2>&1 \
        | grep -v Warning | tail -4
}
large() {  # tsp_large.py ARGS... (eaco options from $EARGS)
    python3 $REPO/experiments/tsp_large.py "$@" ${EARGS:+--eaco-args="$EARGS"} \
        --process-timeout 200 --work $W
}
selection_instance() {  # N: the path of N's random selection instance (instance seed 1)
    python3 -c "import sys; sys.path.insert(0, '$REPO/experiments')
from pathlib import Path; from tsp_large import random_instance
print(random_instance(Path('$W'), $1, 1))"
}
keep() {  # RUN_DIR OUT_JSON [python on d]: an eaco tsp record without its tour, kept in $R
    python3 -c "import json; d = json.load(open('$1/result.json')); d.pop('tour')
${3:-}
json.dump(d, open('$2', 'w'), indent=1)"
}
phase=$1; shift
case $phase in
prof)
    if [ -n "${BEFORE_DIR:-}" ]; then
        install_package /tmp/site_before "$BEFORE_DIR"
        PYTHONPATH=/tmp/site_before profile $R/profile_before.json "$@"
    fi
    profile $R/profile.json "$@"
    ;;
arms)
    IFS=';' read -ra arms <<< "$ARMS"
    for arm in "${arms[@]}"; do
        PROFILE_ARGS="${PROFILE_ARGS:-} ${arm#*=}" profile "$R/profile_${arm%%=*}.json" "$@"
    done
    ;;
select)
    n=$1; s=$2
    IFS=';' read -ra arms <<< "$ARMS"
    for arm in "${arms[@]}"; do
        label=${arm%%=*}
        EARGS="${arm#*=}" large --sizes $n --seconds ${WARMUP:-20} --instance-seeds 1 --seeds 0 \
            --out /tmp/warm_$label.json > /dev/null 2>&1
        for sd in ${SEEDS:-0 1 2}; do
            EARGS="${arm#*=}" large --sizes $n --seconds $s --instance-seeds 1 --seeds $sd \
                --out $R/sel_${n}_${label}_s$sd.json 2>&1 | grep -E "over|gap" | tail -1
        done
    done
    ;;
rep)
    k=$1; s=$2; seeds=$3; wu=$4
    if [ "$k" = d15112 ]; then
        if [ "$wu" != 0 ]; then  # its own programs: d15112's tour sums take one int32 word
            large --sizes --instances d15112 --instance-seconds $wu --seeds 99 \
                --out /tmp/warm_rep.json > /dev/null 2>&1
        fi
        for sd in $seeds; do
            large --sizes --instances d15112 --seeds $sd --out $R/rep_d15112_s$sd.json 2>&1 \
                | grep -o '"gap_percent": [0-9.]*'
        done
    else
        if [ "$wu" != 0 ]; then
            large --sizes $k --seconds $wu --instance-seeds 1 --seeds 0 \
                --out /tmp/warm_rep.json > /dev/null 2>&1
        fi
        for sd in $seeds; do
            # the gap to LKH-3 where the reference is stored, else only over the BHH estimate
            large --sizes $k --seconds $s --instance-seeds 0 --seeds $sd \
                --out $R/rep_${k}_s$sd.json 2>&1 \
                | grep -oE '"(gap_percent|over_bhh_percent)": [0-9.]+' | tail -2
        done
    fi
    ;;
hist)
    n=$1; s=$2; shift 2
    f=$(selection_instance $n)
    python3 -m eaco_jax tsp "$f" --max-seconds 12 --clock call --seed 9 --out /tmp/hwarm \
        > /dev/null 2>&1
    python3 -m eaco_jax tsp "$f" --max-seconds $s --clock call --seed 0 "$@" \
        --out /tmp/h_${n}_$s 2>&1 | tail -4
    cp /tmp/h_${n}_$s/history.csv $R/hist_${n}_$s.csv
    keep /tmp/h_${n}_$s $R/hist_${n}_$s.json
    ;;
flags)
    n=$1; its=$2
    f=$(selection_instance $n)
    IFS=';' read -ra arms <<< "$FLAGS"
    for rep in 1 2; do
        for arm in "${arms[@]}"; do
            label=${arm%%=*}
            XLA_FLAGS="${arm#*=}" python3 -m eaco_jax tsp "$f" --iterations $its --seed 0 \
                --out /tmp/f_$label > /tmp/f_$label.log 2>&1 || tail -3 /tmp/f_$label.log
            keep /tmp/f_$label $R/flags_${label}_$rep.json "d['xla_flags'] = '''${arm#*=}'''
print('$label', $rep, d['best_length'], round(d['seconds_per_iteration'], 4), round(d['compile_seconds'], 1))"
        done
    done
    ;;
envs)
    n=$1; s=$2
    f=$(selection_instance $n)
    IFS=';' read -ra arms <<< "$ENVS"
    for rep in 0 1 2; do  # rep 0: each arm's discarded warm-up (its programs compiled once)
        for arm in "${arms[@]}"; do
            label=${arm%%=*}
            spec=${arm#*=}; assign=${spec%%|*}; opts=""
            [[ $spec == *"|"* ]] && opts=${spec#*|}
            if [ $rep = 0 ]; then
                # shellcheck disable=SC2086
                env $assign python3 -m eaco_jax tsp "$f" --max-seconds 10 --clock call --seed 9 \
                    $opts --out /tmp/ewarm > /dev/null 2>&1
                continue
            fi
            # shellcheck disable=SC2086
            env $assign python3 -m eaco_jax tsp "$f" --max-seconds $s --clock call --seed 0 \
                $opts --out /tmp/e_$label > /tmp/e_$label.log 2>&1 || tail -3 /tmp/e_$label.log
            keep /tmp/e_$label $R/envs_${label}_$rep.json "d.pop('history_best', None)
d['environment'] = '''$assign'''; d['eaco_options'] = '''$opts'''
t = d['timing']; p = t['setup_parts']
print('$label', $rep, d['best_length'], d['iterations'], round(d['seconds_per_iteration'], 4),
      'setup', round(t['setup_seconds'], 2), 'read', round(p['read_seconds'], 2),
      'between', round(p.get('between_chunks_seconds', -1), 2),
      'compile', round(t['compile_seconds'], 2), 'loop', round(t['loop_seconds'], 2))"
        done
    done
    ;;
diag)
    n=$1; s=$2
    f=$(selection_instance $n)
    python3 -m eaco_jax tsp "$f" --max-seconds 12 --clock call --seed 9 --out /tmp/dwarm \
        > /dev/null 2>&1
    JAX_LOG_COMPILES=1 JAX_EXPLAIN_CACHE_MISSES=1 python3 -X importtime -m eaco_jax tsp "$f" \
        --max-seconds $s --clock call --seed 0 --out /tmp/d_log > $R/diag_log_stdout.txt \
        2> $R/diag_log_stderr.txt
    python3 -m cProfile -o /tmp/d.prof -m eaco_jax tsp "$f" --max-seconds $s --clock call \
        --seed 0 --out /tmp/d_prof > /dev/null 2>&1
    python3 -c "import pstats, sys
sys.stdout = open('$R/diag_profile.txt', 'w')
p = pstats.Stats('/tmp/d.prof')
p.sort_stats('cumulative').print_stats(120)
p.sort_stats('tottime').print_stats(60)"
    for k in log prof; do
        keep /tmp/d_$k $R/diag_$k.json "d.pop('history_best', None)"
    done
    ;;
*)
    echo "usage: bash experiments/tsp_gpu.sh prof|arms|select|rep|hist|flags|envs|diag ... (see its header)" >&2
    exit 2
    ;;
esac
(cd $OUT && tar czf tsp_${phase}_$(date +%H%M%S).tgz r && rm -rf r)
