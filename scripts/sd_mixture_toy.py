"""A toy of the swap-calibrated standard-deviation part (issue 21, session 23): does the
calibration fall short under a pure spread difference with iid normal transitions, and does the
shortfall vanish with the transitions per unit?

One state, ``--pairs`` pairs; each member visits with Poisson(n) + 1 transitions (with
probability ``one_sided`` only one member of a pair visits, either at random), A's transitions
N(0, sd_a²), B's N(0, 1). Estimate as scripts/deviation_calibrated_probe.py does for one state:
``(σ̂_A − σ̂_B)²`` less its mean over every swap of the pairs' members under which each side keeps
≥ 2 units, over ``1 − E(a − b)²`` (the assignments' mixing; ``a``, ``b``: A's own share of
transitions on each side). Under a spread difference every swapped side is a mixture of the two
normals, whose kurtosis exceeds 3, so the noise of ``σ̂`` (∝ (κ − 1) σ² / n) is larger under the
swaps than under the observed labels: the calibration subtracts too much, by O(1/n). The
``corrected_`` fields add back the swaps' mean noise less the observed labels' (each side's
delta-method noise from its own second and fourth moments).

    .venv/bin/python scripts/sd_mixture_toy.py --out benchmarks/results/sd_mixture_toy.json
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np

MIN_UNITS = 2
#: (sd of A, transitions per member (Poisson mean), share of one-sided pairs)
GRID = [(1.0, 6, 0.7), (np.sqrt(1.5), 6, 0.7), (np.sqrt(1.5), 6, 0.0), (np.sqrt(1.5), 24, 0.0),
        (np.sqrt(1.5), 96, 0.0), (np.sqrt(1.5), 24, 0.7)]


def _sd_noise(x: np.ndarray) -> float:
    """The delta-method variance of ``σ̂`` from the sample's own central moments:
    ``(m4 − m2²) / (4 m2 n)`` (iid transitions)."""
    centred = x - x.mean()
    m2, m4 = (centred**2).mean(), (centred**4).mean()
    return float((m4 - m2**2) / (4 * m2 * len(x))) if m2 > 0 else 0.0


def _side_stats(values_a, values_b, n_a, n_b, swap):
    """(σ̂_A − σ̂_B)², A's own share on side A less on side B (squared) and the two sides'
    noise of ``σ̂`` (:func:`_sd_noise`), or None where a side holds fewer than MIN_UNITS
    units."""
    side_a = [b if s else a for a, b, s in zip(values_a, values_b, swap, strict=True)]
    side_b = [a if s else b for a, b, s in zip(values_a, values_b, swap, strict=True)]
    if min(sum(len(x) > 0 for x in side_a), sum(len(x) > 0 for x in side_b)) < MIN_UNITS:
        return None
    x_a, x_b = np.concatenate(side_a), np.concatenate(side_b)
    own = n_a[~swap].sum()
    mixing = (own / len(x_a) - (n_a.sum() - own) / len(x_b))**2
    return (x_a.std() - x_b.std())**2, mixing, _sd_noise(x_a) + _sd_noise(x_b)


def one_case(sd_a: float, per_member: int, one_sided: float, pairs: int, reps: int,
             seed: int) -> dict:
    rng = np.random.default_rng(seed)
    swaps = np.array(list(itertools.product([False, True], repeat=pairs)))[1:]
    estimates, corrected = [], []
    for _ in range(reps):
        n_a, n_b = rng.poisson(per_member, (2, pairs)) + 1
        alone, who = rng.random(pairs) < one_sided, rng.random(pairs) < 0.5
        n_a, n_b = np.where(alone & ~who, 0, n_a), np.where(alone & who, 0, n_b)
        values_a = [rng.normal(0.0, sd_a, k) for k in n_a]
        values_b = [rng.normal(0.0, 1.0, k) for k in n_b]
        observed = _side_stats(values_a, values_b, n_a, n_b, np.zeros(pairs, dtype=bool))
        null = [s for s in (_side_stats(values_a, values_b, n_a, n_b, w) for w in swaps)
                if s is not None]
        if observed is None or not null:
            continue
        null = np.array(null)
        estimates.append((observed[0] - null[:, 0].mean()) / (1 - null[:, 1].mean()))
        # the null less the swaps' extra noise over the observed labels' (their difference)
        extra = null[:, 2].mean() - observed[2]
        corrected.append((observed[0] - null[:, 0].mean() + extra) / (1 - null[:, 1].mean()))
    truth = (sd_a - 1.0)**2
    out = {"sd_a": sd_a, "per_member": per_member, "one_sided": one_sided,
           "kept": len(estimates), "truth": truth}
    for name, values in (("", np.array(estimates)), ("corrected_", np.array(corrected))):
        out |= {f"{name}mean": float(values.mean()),
                f"{name}se": float(values.std(ddof=1) / np.sqrt(len(values))),
                f"{name}ratio": float(values.mean() / truth) if truth else None}
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=6)
    parser.add_argument("--reps", type=int, default=4000)
    parser.add_argument("--out", default="sd_mixture_toy.json")
    args = parser.parse_args(argv)
    rows = []
    for k, (sd_a, per_member, one_sided) in enumerate(GRID):
        rows.append(one_case(float(sd_a), per_member, one_sided, args.pairs, args.reps, k))
        print(json.dumps(rows[-1]), flush=True)
    Path(args.out).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
