#!/usr/bin/env bash
# Table 1's network rows on another CPU code path, compared with this clone's (issue #36).
#
#   bash scripts/cross_code_path.sh DIR [STAGE ...]
#
# Clones this repository into DIR (a new folder beside this clone, so the relative DVC remote
# resolves), sets up its environment, pulls every committed output from the DVC remote, and
# re-runs the stages that train or score a network with ATEN_CPU_CAPABILITY=default (torch's
# own kernels without AVX2/AVX-512: the one setting that changes float32 training on an
# AVX-512 host, benchmarks/cpu_code_path.py). The corpus, poses, samples and GPR models stay
# the pulled ones: they train no network. Then scripts/seed_spread.py judges each network row:
# the medians over seeds of the two trees agree when they differ by no more than the larger
# spread (max - min over seeds). Default stages: every network fit and evaluation of Table 1's
# rigs (fit_nn, fit_nn_joint_space, their replicate seeds, evaluate, evaluate_seed), for the
# built-in rigs and the Blender ones; one stage at a time (the values matter here, not the time),
# each on one thread as `rigmap reproduce` runs them (rigmap.reproduce.STAGE_THREADS).
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: bash scripts/cross_code_path.sh DIR [STAGE ...]" >&2; exit 2; }
here="$(cd "$(dirname "$0")/.." && pwd)"
target="$1"
shift
[ ! -e "$target" ] || { echo "cross_code_path: $target exists; give a new folder" >&2; exit 2; }

git clone --quiet "$here" "$target"
cd "$target"
make setup blender > cross_code_path_setup.log 2>&1
export PATH="$PWD/.venv/bin:$PATH"
dvc pull --quiet
dvc repro --single-item check_params > /dev/null

if [ $# -eq 0 ]; then
    # the network stages by family (the dvc.yaml keys before '@'), in DVC's order; DVC
    # addresses a stage of stages/<family>/dvc.yaml as that path, a colon and its name
    # every fit before any evaluation: an evaluation must score the networks this code path
    # trained, not the pulled ones (DVC's listing puts evaluate@<rig> before the joint-space fit)
    mapfile -t stages < <(dvc stage list --all --name-only > stage_list.txt
        grep -E '^(stages/[a-z_]+/dvc.yaml:)?(fit_nn|fit_nn_blender|fit_nn_joint_space|fit_nn_seed|fit_nn_seed_blender|fit_nn_joint_space_seed)(@|$)' stage_list.txt \
            | grep -v -E 'fit_nn@.*-(none|uniform|univariate_gaussian|multivariate_gaussian|gmm)$'
        grep -E '^(stages/[a-z_]+/dvc.yaml:)?(evaluate|evaluate_blender|evaluate_seed|evaluate_seed_blender)(@|$)' stage_list.txt)
else
    stages=("$@")
fi
echo "cross_code_path: ${#stages[@]} stage(s) on ATEN_CPU_CAPABILITY=default"
for stage in "${stages[@]}"; do
    ATEN_CPU_CAPABILITY=default OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        dvc repro --force --single-item "$stage" > "cross_code_path_${stage//[@:\/]/_}.log" 2>&1 \
        || { echo "cross_code_path: $stage failed (see its log in $target)" >&2; exit 1; }
    echo "cross_code_path: done $stage"
done
python "$here/scripts/seed_spread.py" "$here/metrics" "$target/metrics"
