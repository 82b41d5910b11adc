#!/usr/bin/env bash
# `make demo`: the main job on the embedded default data. Usage: demo.sh SIMCRED OUT_DIR
set -euo pipefail
simcred=$1
out=$2
rm -rf "$out"
echo "== 1. built-in example trace sets (seeded lane changes: baseline, and a variant 20 % faster)"
"$simcred" example --out "$out/data" --runs 400 --steps 100 --seed 0
"$simcred" --quiet example --out "$out/data/repeat" --runs 400 --steps 100 --seed 1 \
  --duration-scale 1.0
echo
echo "== 2. compare baseline vs variant on (y, heading): the paper's bound test"
"$simcred" compare "$out/data/baseline" "$out/data/variant" --features y,heading --bins 10 \
  --test bound --seed 0 --out "$out/compare-bound"
echo
echo "== 3. the same with a permutation test (999 permutations)"
"$simcred" compare "$out/data/baseline" "$out/data/variant" --features y,heading --bins 10 \
  --test permutation --seed 0 --out "$out/compare-permutation"
echo
echo "== 4. distance matrix: baseline, an independent repeat of it, and the variant"
"$simcred" matrix "$out/data/baseline" "$out/data/repeat/baseline" "$out/data/variant" \
  --names baseline,repeat,variant --features y,heading --test permutation --seed 0 \
  --out "$out/matrix"
echo
echo "== 5. seed 000, sec. VI at a reduced size (500 runs per set): SimpleCar λ sweep and T-junction"
"$simcred" paper 000 --out "$out/paper000" --runs 500 --workers 2
echo
echo "== 6. seed 002: the cut-in reprocessed (fit, resimulation, risk, errors) and varied 300 times"
"$simcred" paper 002 --out "$out/paper002" --workers 2
echo
echo "== 7. a real A9 recording (sensor data only), reprocessed"
a9="$(dirname "$0")/../../shared/data/real/osc-generator-a9/trajectories_file.csv"
if [ -f "$a9" ]; then
  "$simcred" reprocess "$a9" --out "$out/a9" --threshold 0.1
else
  echo "(skipped: $a9 not found)"
fi
echo
echo "Outputs in $out/: compare-*/comparison.json, compare-*/state_map.png, matrix/matrix.{json,csv,png},"
echo "  paper000/ (fig5_inputs.png, fig6_xy.png, fig7_xy_heading.png, table3_*.png, claims.json),"
echo "  paper002/ (figures/fig3..fig7, errors.json, reaction.json, scenario.xosc, claims.json), a9/"
