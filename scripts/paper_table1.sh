#!/usr/bin/env bash
# Table 1 at the paper's budget (experiment=paper) for the quadruped and the biped, and the
# wall time of each stage: the stage scripts Table 1 needs, run one after another into their
# own folders (paths.data/models/metrics under OUT, default paper-run/), then the report's
# Table 1 and figures into reports/paper/ (issue #15).
#
# Why not `rigmap reproduce experiment=paper --target evaluate@<rig>`: dvc's evaluate stage
# depends on every model of the rig, and at the paper's size that is every sampler's
# 100 000-sample network (Table 2's sweep): about 21 h on 2 cores. Table 1 needs four
# models a rig; the network (minibatch 8, 20 epochs over 100 885 rows) is most of it, about
# 46 min a rig at a load of 2-4.
#
#   scripts/paper_table1.sh                      # both rigs, then reports/paper/
#   RIGS=quadruped scripts/paper_table1.sh       # one rig
#   scripts/paper_table1.sh budget.samples=500 budget.epochs=1   # extra Hydra overrides (a smoke run)
#
# Stage times go to OUT/<rig>.times ("<stage> <seconds> load_after=<1-min load>"), logs to
# OUT/<rig>.log; reports/paper/stage_times.md gathers the times.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-paper-run}
RIGS=${RIGS:-"quadruped biped"}
REPORTS=${REPORTS:-reports/paper}
BIN=${BIN:-.venv/bin}
case $BIN in /*) ;; *) BIN=$PWD/$BIN ;; esac
export PATH="$BIN:$PATH" MKL_CBWR=AVX2 ATEN_CPU_CAPABILITY=avx2
mkdir -p "$OUT"
PATHS="paths.data=$OUT/data paths.models=$OUT/models paths.metrics=$OUT/metrics"
COMMON="experiment=paper seed=0 $PATHS $*"

run() {  # run <rig> <stage name> <command...>: time it, append its output to the rig's log
  local rig=$1 name=$2
  shift 2
  local start end
  echo "== $name: $* (load $(cut -d' ' -f1 /proc/loadavg))" >> "$OUT/$rig.log"
  start=$(date +%s.%N)
  if ! "$@" >> "$OUT/$rig.log" 2>&1; then
    echo "paper_table1: $rig: stage $name failed; see $OUT/$rig.log" >&2
    exit 1
  fi
  end=$(date +%s.%N)
  printf '%s %.1f load_after=%s\n' "$name" "$(python -c "print($end - $start)")" \
    "$(cut -d' ' -f1 /proc/loadavg)" >> "$OUT/$rig.times"
}

for rig in $RIGS; do
  : > "$OUT/$rig.times"
  run "$rig" animate python pipelines/animate.py rig="$rig" $COMMON
  run "$rig" pose python pipelines/pose.py rig="$rig" $COMMON
  run "$rig" supersample_pca_gaussian python pipelines/supersample.py rig="$rig" sampler=pca_gaussian $COMMON
  run "$rig" fit_nn_pca_gaussian python pipelines/fit.py rig="$rig" regressor=nn sampler=pca_gaussian regressor.progress=false $COMMON
  run "$rig" fit_gpr_multiquadric python pipelines/fit.py rig="$rig" regressor=gpr sampler=none kernel=multiquadric $COMMON
  run "$rig" fit_mean python pipelines/fit.py rig="$rig" regressor=mean sampler=none $COMMON
  run "$rig" fit_nn_joint_space python pipelines/fit.py rig="$rig" regressor=nn_joint_space sampler=none regressor.progress=false $COMMON
  run "$rig" evaluate python pipelines/evaluate.py rig="$rig" evaluate.set=methods $COMMON
done

python scripts/paper_report.py --out "$OUT" --reports "$REPORTS" --rigs $RIGS
