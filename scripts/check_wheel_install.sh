#!/usr/bin/env bash
# A non-editable install works on its own: build simcred from a copy of the source (pyproject.toml,
# README.md, src/), `pip install` it into a fresh virtual environment, and from a folder outside
# the repository run `simcred paper all` (small sizes) and `simcred validate` on the shipped
# cut-in example (examples/validate/cutin). Package data that a wheel forgets fails here.
#
# Usage: scripts/check_wheel_install.sh [WORK_DIR]   (default: a new temporary folder, removed)
# PYTHON picks the interpreter of the new environment (default: python3). pip installs the
# dependencies from the configured index (a local mirror, its cache or the internet).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
python=${PYTHON:-python3}
if [ $# -ge 1 ]; then
  work=$1
  rm -rf "$work" && mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi
work=$(cd "$work" && pwd)
start=$SECONDS
step() { echo "== [$((SECONDS - start)) s] $*"; }

step "copy the source (no build/, egg-info or caches end up in the repository)"
mkdir "$work/source"
tar -C "$root" --exclude='__pycache__' --exclude='*.egg-info' --exclude='*.pyc' \
  -cf - pyproject.toml README.md src | tar -C "$work/source" -xf -

step "fresh virtual environment; pip install (not editable)"
"$python" -m venv "$work/venv"
bin=$work/venv/bin
"$bin/python" -m pip install --quiet --disable-pip-version-check "$work/source"
rm -rf "$work/source"  # the installed copy is all there is now

cd "$work"  # outside the repository: nothing can be found relative to it
location=$("$bin/python" -c "import simcred, pathlib; print(pathlib.Path(simcred.__file__).parent)")
case "$location" in
  "$work/venv/"*) ;;
  *) echo "simcred imported from $location, not from the new environment" >&2; exit 1 ;;
esac

step "simcred paper all (small sizes)"
"$bin/simcred" --quiet paper all --out "$work/all" --runs 2 --variations 20 --seed 0
for file in claims.json paper003/findings.json; do
  [ -s "$work/all/$file" ] || { echo "paper all wrote no $file" >&2; exit 1; }
done

step "simcred validate on the shipped cut-in example"
cp -r "$root/examples/validate/cutin" "$work/cutin"
"$bin/python" "$work/cutin/make_runs.py" --out "$work/cutin"
code=0
"$bin/simcred" --quiet validate "$work/cutin/validation.yaml" --out "$work/validate" || code=$?
case $code in  # 0 valid, 1 not valid, 3 inconclusive: all answers; 2 bad input, 70 a defect
  0|1|3) ;;
  *) echo "simcred validate exited $code" >&2; exit 1 ;;
esac
[ -s "$work/validate/verdict.json" ] || { echo "validate wrote no verdict.json" >&2; exit 1; }
step "done: the installed simcred runs paper all and validate (validate exit $code)"
