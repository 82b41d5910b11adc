"""The shift's interval from a bias-reduced cluster-robust standard error (CR2) instead of the
cluster bootstrap (issue 21, interval coverage; paired designs, tests/response_designs.py
``defect``, ``--pairs`` pairs, seeds 0 to ``--reps`` − 1).

The shift ``Σ_s w_s (μ_A,s − μ_B,s)`` is a smooth function of the clusters' (pairs') sums, so
its first-order (infinitesimal-jackknife) influence of cluster ``c`` is

    ψ_c = Σ_s w_s (e_A,cs / N_A,s − e_B,cs / N_B,s) + Σ_s ∂u_s/∂ω_c (D_s − shift) / U

(``e_g,cs = S_g,cs − μ_g,s N_g,cs`` the cluster's residual sum in state ``s`` on side ``g``,
``u_s`` the unnormalised weight, ``U = Σ u``, ``D_s`` the state's difference of means). CR0 is
``Σ ψ_c²``, which under-estimates with few clusters per state (each residual is shrunk by its
own leverage ``h = N_g,cs / N_g,s``); CR2 (Bell & McCaffrey 2002) divides each residual by
``√(1 − h)``, CR3 (≈ the delete-one jackknife) by ``1 − h``. Per replication: the shipped
basic-bootstrap bounds and the three standard errors' t intervals (``n − 1`` degrees of
freedom, ``n`` the pairs), scored against the true shifts of
benchmarks/results/response_coverage_s14.json (means over 30 draws of 1,500 pairs), and each
standard error's mean over the replications against the shift's sampling standard deviation.
``ψ`` is checked against a numerical derivative of :meth:`ClusterSums.deviation` on every
replication (``max_psi_error``).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/shift_cr2_probe.py --reps 400 \\
        --out benchmarks/results/shift_cr2_probe.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.stats import t as student

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))
import response_coverage  # noqa: E402
from deviation_calibrated_probe import _per_pair  # noqa: E402

import response_designs  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402

RESPONSES = ("dv", "a")  # gap and v are kinematic consequences here (shift ~1e-15)
LEVELS = (0.90, 0.95)
ERRORS = ("cr0", "cr2", "cr3")


def influences(entries: Entries, keep: np.ndarray, j: int) -> dict[str, np.ndarray]:
    """Per standard error of :data:`ERRORS`: the clusters' influences on the shift of response
    ``j`` (module docs), the mean part's residuals divided by ``(1 − h)^p``, p = 0, ½, 1; and
    the shift itself."""
    take = keep[entries.state]
    state = (np.cumsum(keep) - 1)[entries.state[take]]
    sums = _per_pair(entries, take, state)  # (1 + 2J, 2, states, pairs)
    n, s = sums[0], sums[1 + j]
    totals = entries.totals().T  # (2, clusters) over all states
    n_gs, s_gs, n_g = n.sum(axis=2), s.sum(axis=2), totals.sum(axis=1)
    mean = s_gs / n_gs
    u = 0.5 * (n_gs[0] / n_g[0] + n_gs[1] / n_g[1])
    w, d = u / u.sum(), mean[0] - mean[1]
    shift = float((w * d).sum())
    residual = (s - mean[..., None] * n) / n_gs[..., None]  # (2, states, clusters)
    d_u = 0.5 * sum((n[g] - n_gs[g][:, None] * totals[g] / n_g[g]) / n_g[g] for g in (0, 1))
    weight_part = ((d - shift)[:, None] * d_u).sum(axis=0) / u.sum()
    leverage = n / n_gs[..., None]
    out = {"shift": np.array(shift)}
    for name, power in zip(ERRORS, (0.0, 0.5, 1.0), strict=True):
        with np.errstate(invalid="ignore", divide="ignore"):
            scaled = np.nan_to_num(residual / (1 - np.minimum(leverage, 1 - 1e-12))**power)
        out[name] = (w[:, None] * (scaled[0] - scaled[1])).sum(axis=0) + weight_part
    return out


def numeric_check(entries: Entries, keep: np.ndarray, psi: list[np.ndarray]) -> float:
    """Largest relative gap between the analytic CR0 influences and a central difference of
    :meth:`ClusterSums.deviation` in each cluster's weight."""
    n, eps = entries.n_clusters, 1e-5
    sums = ClusterSums.of(entries, keep)
    up = sums.deviation(np.ones((n, n)) + eps * np.eye(n))["shift"]
    down = sums.deviation(np.ones((n, n)) - eps * np.eye(n))["shift"]
    numeric = (up - down) / (2 * eps)
    analytic = np.array(psi)
    return float(np.abs(numeric - analytic).max() / max(np.abs(numeric).max(), 1e-300))


def recording(into: list):
    """``response_effects`` that also appends, per call and response: the shift, the shipped
    bootstrap bounds at each level, each standard error and the derivative check."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        row, cr0 = {}, []
        for j, f in enumerate(out.features):
            found = influences(entries, keep, j)
            cr0.append(found["cr0"])
            row[f.feature] = {"shift": f.shift, "shift_check": float(found["shift"]),
                              "clusters": entries.n_clusters} | {
                name: float(np.sqrt((found[name]**2).sum())) for name in ERRORS} | {
                f"boot_{level}": f.shift_bounds((1 - level) / 2) for level in LEVELS}
        gap = numeric_check(entries, keep, cr0)
        for r in row.values():
            r["psi_error"] = gap
        into.append(row)
        return out
    return wrapped


def summary(rows: list, truth: dict) -> dict:
    out = {}
    for name in RESPONSES:
        t0 = truth[name]
        shift = np.array([r[name]["shift"] for r in rows])
        n = np.array([r[name]["clusters"] for r in rows])
        cell = {"true_shift": t0, "sampling_sd": float(shift.std(ddof=1)),
                "max_shift_gap": float(np.max(np.abs(shift - [r[name]["shift_check"]
                                                             for r in rows]))),
                "max_psi_error": float(max(r[name]["psi_error"] for r in rows))}
        for level in LEVELS:
            low, high = np.array([r[name][f"boot_{level}"] for r in rows]).T
            cell[f"bootstrap_{level}"] = float(np.mean((low <= t0) & (t0 <= high)))
            cell[f"bootstrap_{level}_low_above"] = float(np.mean(low > t0))
        for se_name in ERRORS:
            se = np.array([r[name][se_name] for r in rows])
            cell[f"{se_name}_over_sampling"] = float(se.mean() / cell["sampling_sd"])
            for level in LEVELS:
                q = student.ppf(1 - (1 - level) / 2, n - 1)
                cover = np.abs(shift - t0) <= q * se
                cell[f"{se_name}_{level}"] = float(cover.mean())
                cell[f"{se_name}_{level}_low_above"] = float(np.mean(shift - q * se > t0))
        out[name] = cell
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--pairs", type=int, default=40)
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--truth", default=str(ROOT / "benchmarks/results/"
                                               "response_coverage_s14.json"))
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    truths = json.loads(Path(args.truth).read_text())["table"]
    result = {}
    for kind in args.kinds.split(","):
        found: list = []
        conditional.response_effects = recording(found)
        for rep in range(args.seed0, args.seed0 + args.reps):
            d = response_designs.defect(np.random.default_rng(rep), kind, runs=args.pairs)
            response_coverage.effects(d, rep, 500)
        truth = {name: truths[kind][name]["true_shift"] for name in RESPONSES}
        result[kind] = summary(found, truth)
        for name, cell in result[kind].items():
            print(kind, name, {k: round(v, 4) for k, v in cell.items()}, flush=True)
    if args.out:
        args.out.write_text(json.dumps({"args": vars(args) | {"out": str(args.out)},
                                        "table": result}, indent=1) + "\n")


if __name__ == "__main__":
    main()
