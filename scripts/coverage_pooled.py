"""Coverage of the effect intervals pooled over every committed run, with its Monte Carlo error
(issue 21, interval coverage; session 30).

A coverage from ``n`` draws has a Monte Carlo standard error ``√(c (1 − c) / n)`` at its nominal
``c``: 2.1 points at 90 % and 200 draws. A rule that asks every cell of a run to lie within ±3
points therefore fails an exactly calibrated interval often (six cells at both levels, 200 draws
each: in about three runs of four), so the runs of one interval are pooled here and each pooled
cell is read against the band with its error (Morris, White & Crowther, Using simulation studies
to evaluate statistical methods, Stat. Med. 38, 2019): ``within`` (the estimate inside ±3
points), ``near`` (outside, by less than 1.96 standard errors) or ``outside``. Nothing is left
out: every committed run of the interval at that size enters with its number of draws.

    .venv/bin/python scripts/coverage_pooled.py --out benchmarks/results/coverage_pooled.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
CELLS = [(kind, feature) for kind in ("variance", "delay", "clip") for feature in ("dv", "a")]
LEVELS = ("0.9", "0.95")
BAND = 0.03

# interval -> size -> committed runs (file stems under benchmarks/results)
COVERAGE_RUNS = {"shift": "shift_coverage", "deviation (shipped)": "coverage"}
RESPONSE_COVERAGE = {
    "40": ["response_coverage_s28", "response_coverage_s28_seed10000"],
    "160": ["response_coverage_s28_160", "response_coverage_s28_160_seed10000",
            "response_coverage_s28_160_seed10000_variance_clip"]}
R_INV = {
    "40": ["deviation_noise_probe_permutation_floor",
           *(f"deviation_noise_probe_permutation_floor_seed{s}"
             for s in (10000, 10100, 20000, 20100))],
    "160": ["deviation_noise_probe_permutation_floor_160",
            *(f"deviation_noise_probe_permutation_floor_160_seed{s}"
              for s in (100, 250, 20000, 20150))]}
#: the calibrated probe's intervals: r_inv (the one stated before the fresh seeds) first, then
#: its relatives for comparison (same draws; not a selection: none is stated as a candidate)
CALIBRATED = (("r_inv", 24), ("rf_inv", 25), ("c_inv", 24), ("g_inv", 24), ("u_inv", 24))
STUDENT_CROSS = {"40": ["deviation_excess_probe_40"],
                 "160": ["deviation_excess_probe_160",
                         *(f"deviation_excess_probe_160_seed{s}" for s in (10000, 10100))]}


def _load(stem: str) -> dict | None:
    path = RESULTS / f"{stem}.json"
    return json.loads(path.read_text()) if path.exists() else None


def _response_coverage(stem: str, field: str):
    """(draws, {cell: {level: coverage}}) of a scripts/response_coverage.py run."""
    found = _load(stem)
    if found is None:
        return None
    table = found["table"]
    return int(found["args"]["reps"]), {
        (kind, f): table[kind][f][field] for kind, f in CELLS if kind in table}


def _calibrated_probe(stem: str, label: str):
    """The same of a scripts/deviation_calibrated_probe.py run (``r_inv`` or another field)."""
    found = _load(stem)
    if found is None:
        return None
    table = found["table"]
    return int(found["args"]["reps"]), {
        (kind, f): {lv: table[kind][f][f"{label}_{lv}"] for lv in LEVELS}
        | {"equivalent": table[kind][f].get(f"{label}_equivalent_at_truth")}
        for kind, f in CELLS if kind in table}


def _student_cross(stem: str):
    """The same of a scripts/deviation_excess_probe.py run."""
    found = _load(stem)
    if found is None:
        return None
    cells = found["cells"]
    return int(found["args"]["reps"]), {
        (kind, f): {lv: cells[f"{kind}/{f}"][f"student_cross_{lv}"][0] for lv in LEVELS}
        for kind, f in CELLS if f"{kind}/{f}" in cells}


def pooled(runs: list) -> dict:
    """Per cell and level: the draws, the pooled coverage, its Monte Carlo error at the nominal
    level and the reading against the band (module docs)."""
    out = {}
    for cell in CELLS:
        parts = [(n, table[cell]) for n, table in runs if cell in table]
        n = sum(p[0] for p in parts)
        if not n:
            continue
        row = {"draws": n}
        for lv in LEVELS:
            nominal = float(lv)
            value = sum(k * t[lv] for k, t in parts) / n
            error = (nominal * (1 - nominal) / n) ** 0.5
            distance = max(abs(value - nominal) - BAND, 0.0)
            row[lv] = {"coverage": round(value, 4), "mc_se": round(error, 4),
                       "reading": "within" if distance == 0 else
                       "near" if distance < 1.96 * error else "outside"}
        equivalent = [(k, t.get("equivalent")) for k, t in parts]
        if all(e is not None for _, e in equivalent):
            row["equivalent_at_truth"] = round(sum(k * e for k, e in equivalent) / n, 4)
        out["/".join(cell)] = row
    return out


def collect() -> dict:
    intervals = {}
    for name, field in COVERAGE_RUNS.items():
        intervals[name] = {size: [r for r in (_response_coverage(s, field) for s in stems) if r]
                           for size, stems in RESPONSE_COVERAGE.items()}
    for label, session in CALIBRATED:
        intervals[f"{label} (session {session}, probe)"] = {
            size: [r for r in (_calibrated_probe(s, label) for s in stems) if r]
            for size, stems in R_INV.items()}
    intervals["student_cross (session 29, probe)"] = {
        size: [r for r in map(_student_cross, stems) if r] for size, stems in STUDENT_CROSS.items()}
    return {name: {size: pooled(runs) for size, runs in sizes.items()}
            for name, sizes in intervals.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    found = collect()
    for name, sizes in found.items():
        for size, cells in sizes.items():
            readings = [cells[c][lv]["reading"] for c in cells for lv in LEVELS]
            print(f"{name}, {size} pairs: within {readings.count('within')}, near "
                  f"{readings.count('near')}, outside {readings.count('outside')}")
            for cell, row in cells.items():
                print(f"  {cell:12} n={row['draws']:4} " + "  ".join(
                    f"{lv}: {row[lv]['coverage']:.4f} ±{row[lv]['mc_se']:.4f} {row[lv]['reading']}"
                    for lv in LEVELS)
                      + (f"  equivalent at truth {row['equivalent_at_truth']:.4f}"
                         if "equivalent_at_truth" in row else ""))
    if args.out:
        args.out.write_text(json.dumps(found, indent=1) + "\n")


if __name__ == "__main__":
    main()
