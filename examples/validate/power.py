"""Error rates of learned validity domains on the synthetic universe (docs/validate.md).

The candidate equals the reference below v = 20 m/s and deviates by ``effect`` in the AR(1)
coefficient above it (simcred.validate.synthetic). For each effect and seed, the loop learns the
domain over the cells 5-10-15-20-25-30 m/s and we count, per cell, what it declared:

* below 20 m/s (truly valid): cells declared *not valid* (false alarms, level alpha per cell);
* above 20 m/s (deviating): cells declared *valid* (false validations) and *not valid* (power).

Usage: python examples/validate/power.py [--seeds 20] [--out power.json]
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

from simcred.validate.loop import Inputs, validate
from simcred.validate.synthetic import universe, validation_spec

EFFECTS = (0.0, 0.05, 0.1, 0.15, 0.2)


def outcome(effect: float, seed: int, runs: int = 100, steps: int = 150) -> Counter:
    """Per (side of the switch, status): how many cells."""
    reference = universe(runs, steps, seed=1000 + seed)
    candidate = universe(runs, steps, seed=2000 + seed, effect=effect, v_switch=20, name="sim")
    result = validate(validation_spec(seed), Inputs(reference, {"sim": candidate}, ()))
    counts = Counter()
    for cell in result.domains["sim"].cells:
        side = "above" if cell.index[0] >= 3 else "below"
        counts[side, cell.status.value] += 1
    return counts


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    table = []
    print(f"{'effect':>6} {'false alarms below':>20} {'valid above':>12} {'not valid above':>16}"
          f" {'unknown':>8} {'power':>6}")
    for effect in EFFECTS:
        total = Counter()
        for seed in range(args.seeds):
            total.update(outcome(effect, seed))
        above = sum(v for (side, _), v in total.items() if side == "above")
        below = sum(v for (side, _), v in total.items() if side == "below")
        row = {"effect": effect, "seeds": args.seeds,
               "below_cells": below, "below_not_valid": total["below", "not valid"],
               "above_cells": above, "above_valid": total["above", "valid"],
               "above_not_valid": total["above", "not valid"],
               "unknown": total["below", "unknown"] + total["above", "unknown"],
               "power": total["above", "not valid"] / above}
        table.append(row)
        print(f"{effect:>6} {row['below_not_valid']:>14} / {below:<3} {row['above_valid']:>6} / "
              f"{above:<3} {row['above_not_valid']:>10} / {above:<3} {row['unknown']:>8} "
              f"{row['power']:>6.2f}")
    if args.out:
        with open(args.out, "w") as f:
            json.dump(table, f, indent=1)


if __name__ == "__main__":
    main()
