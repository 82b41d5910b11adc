#!/usr/bin/env bash
# Runs `simcred reprocess` on the cut-in and the A9 recording into DIR (issue 12: the
# restructuring must leave these outputs byte-identical; compare two DIRs with
# scripts/compare_outputs.py).
set -euo pipefail
DIR=${1:?usage: reprocess_baseline.sh DIR}
SIMCRED=${SIMCRED:-simcred}
A9=${A9:-$($SIMCRED data path a9/trajectories_file.csv)}
mkdir -p "$DIR"
$SIMCRED --quiet simulate cutin --out "$DIR/m"
$SIMCRED --quiet reprocess "$DIR/m" --out "$DIR/cutin"
$SIMCRED --quiet reprocess "$A9" --out "$DIR/a9" --threshold 0.1
$SIMCRED --quiet vary "$DIR/cutin/descriptions/fit_GT.json" -n 24 --seed 1 --out "$DIR/vary"
