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
echo "== 5. all three methods at the sizes the papers' claims are made for: simcred paper all"
echo "   paper 000: SimpleCar sweep + T-junction (full size); paper 002: cut-in reprocessed and"
echo "   varied 300 times; paper 003: configuration, quotient, monitors"
"$simcred" paper all --out "$out/all" --variations 300 --workers 2
echo
echo "== 6. the report"
"$simcred" report "$out/all"
echo
echo "== 7. a real A9 recording (sensor data only, shipped in simcred.data), reprocessed"
a9="$("$simcred" data path a9/trajectories_file.csv)"
"$simcred" reprocess "$a9" --out "$out/a9" --threshold 0.1
echo "   and one obstacle of a real NGSIM scene (CommonRoad, BSD-3, tests/data) as the TO, its"
echo "   follower as the EGO"
"$simcred" reprocess tests/data/commonroad-ngsim/USA_US101-3_3_T-1.xml --object 394 \
  --out "$out/ngsim-394"
echo
echo "== 8. real data meets a real simulator: OpenACC human car following (shipped) vs SUMO"
echo "   Krauss/IDM/EIDM/ACC replaying the recorded leaders, and vs real ACC, per speed band"
"$simcred" study car-following --out "$out/study" --seed 0
echo
echo "== 9. validate: is SUMO-IDM valid for car following at 10-25 m/s? (real OpenACC reference)"
python=$(dirname "$simcred")/python
for example in car_following cutin; do  # a copy, so the runs are written beside it, not in the repo
  mkdir -p "$out/validate-examples" && cp -r "examples/validate/$example" "$out/validate-examples/"
done
cf="$out/validate-examples/car_following"
"$python" "$cf/make_runs.py" --out "$cf"
"$simcred" validate "$cf/validation.yaml" --out "$out/validate-cf" \
  || [ $? -eq 1 ]  # exit 1 = "not valid": the answer, not a failure
echo
echo "== 10. validate: is the KS resimulation valid for the paper-002 cut-in? (manufactured data)"
cutin="$out/validate-examples/cutin"
"$python" "$cutin/make_runs.py" --out "$cutin"
"$simcred" validate "$cutin/validation.yaml" --out "$out/validate-cutin"
echo
echo "Outputs in $out/: compare-*/, matrix/, all/ (paper000/, paper002/, paper003/, claims.json), a9/,"
echo "  ngsim-394/ (a CommonRoad obstacle reprocessed: JSON, descriptions, scenario.xosc, figures),"
echo "  study/ (study.json, matrix.csv/png, headway.png, bands/, maps/, comparisons/),"
echo "  validate-cf/ and validate-cutin/ (verdict.json, contracts.yaml, report.html)"
echo
echo "The report: $(cd "$out/all" && pwd)/index.html"
