"""Literal, sample-based reference implementation ("oracle") of the comparison method of
Neurohr et al. 2023.

Paper: seeds/000_8ef4c7b231790a1f.txt, sections IV (MMD, kernels, threshold) and V (process,
eq. 6); precise reading: docs/comparison.md, "The process" and "MMD, kernels, tests". The
production code works on counts; this file works on individual samples, the slow and obvious way,
so tests can compare the two.
Only numpy/scipy.
"""

import math

import numpy as np
from scipy.spatial.distance import cdist

K_BOUND = 1.0  # K = sup k(x, y) for all three kernels (docs/comparison.md: "MMD, kernels...")


def literal_edges(a_runs, b_runs, bins):
    """Equal-frequency binning on the pooled values of both sets (sec. V-A, Fig. 3;
    docs/comparison.md, "The process", 2).

    Per feature j: np.unique(np.quantile(all values of feature j in A and B,
                                         [k/B for k = 1..B-1]))."""
    pooled = np.vstack(list(a_runs) + list(b_runs))
    levels = [k / bins for k in range(1, bins)]
    return [np.unique(np.quantile(pooled[:, j], levels)) for j in range(pooled.shape[1])]


def literal_states(run, edges):
    """State of each sample = vector of bin indices, searchsorted(edges_j, value, side="right")."""
    return np.column_stack(
        [np.searchsorted(edges[j], run[:, j], side="right") for j in range(run.shape[1])]
    ).astype(int)


def literal_median_bandwidth(X, Y, metric):
    """sigma = median of {||x - y|| : x in X, y in Y} with multiplicity (eqs. 3, 4;
    docs/comparison.md, "MMD, kernels, tests").

    If the median is 0: median of the non-zero cross distances; if there is none, return None
    (X and Y are all one and the same point)."""
    d = cdist(X, Y, metric).ravel()
    sigma = np.median(d)
    if sigma == 0:
        nonzero = d[d > 0]
        if nonzero.size == 0:
            return None
        sigma = np.median(nonzero)
    return float(sigma)


def literal_kernel_matrix(P, Q, kernel, sigma, n_bins):
    """K[i, j] = k(P[i], Q[j]).

    gaussian (eq. 3): exp(-||p - q||_2^2 / (2 sigma^2));
    laplace (eq. 4):  exp(-||p - q||_1 / sigma);
    linear (eq. 5, scaled to [0, 1]): <p, q> / sum_j (n_bins[j] - 1)^2, the largest <x, x> on the
    grid of bin indices."""
    if kernel == "gaussian":
        return np.exp(-(cdist(P, Q, "euclidean") ** 2) / (2.0 * sigma**2))
    if kernel == "laplace":
        return np.exp(-cdist(P, Q, "cityblock") / sigma)
    if kernel == "linear":
        scale = sum((b - 1) ** 2 for b in n_bins)
        if scale == 0:  # one bin per feature: every state is the zero vector
            return np.zeros((len(P), len(Q)))
        return (P @ Q.T) / scale
    raise ValueError(f"unknown kernel {kernel!r}")


def _bandwidth(X, Y, kernel):
    metric = {"gaussian": "euclidean", "laplace": "cityblock"}.get(kernel)
    return None if metric is None else literal_median_bandwidth(X, Y, metric)


def literal_mmd(X, Y, kernel, n_bins, estimator="biased"):
    """biased: MMD_b = sqrt(max(0, MMD_b^2)), MMD_b^2 the estimator of sec. IV-B (Gretton eq. 5):
        1/m^2 sum_{i,j} k(x_i, x_j) - 2/(mn) sum_{i,j} k(x_i, y_j) + 1/n^2 sum_{i,j} k(y_i, y_j).
    unbiased: MMD^2_u (Gretton et al. 2012 eq. 3), diagonal terms left out:
        1/(m(m-1)) sum_{i!=j} k(x_i, x_j) + 1/(n(n-1)) sum_{i!=j} k(y_i, y_j)
        - 2/(mn) sum_{i,j} k(x_i, y_j).
    Gaussian/Laplace bandwidth from literal_median_bandwidth(X, Y); None -> statistic 0.0."""
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    m, n = len(X), len(Y)
    sigma = _bandwidth(X, Y, kernel)
    if kernel in ("gaussian", "laplace") and sigma is None:
        return 0.0
    Kxx = literal_kernel_matrix(X, X, kernel, sigma, n_bins)
    Kxy = literal_kernel_matrix(X, Y, kernel, sigma, n_bins)
    Kyy = literal_kernel_matrix(Y, Y, kernel, sigma, n_bins)
    if estimator == "biased":
        mmd2 = Kxx.sum() / m**2 - 2.0 * Kxy.sum() / (m * n) + Kyy.sum() / n**2
        return float(math.sqrt(max(0.0, mmd2)))
    if estimator == "unbiased":
        if m < 2 or n < 2:
            raise ValueError("unbiased MMD needs at least 2 samples per set")
        xx = (Kxx.sum() - np.trace(Kxx)) / (m * (m - 1))
        yy = (Kyy.sum() - np.trace(Kyy)) / (n * (n - 1))
        return float(xx + yy - 2.0 * Kxy.sum() / (m * n))
    raise ValueError(f"unknown estimator {estimator!r}")


def literal_threshold(m, n, alpha, estimator="biased"):
    """Acceptance bound, K = 1.
    biased (sec. IV-B, generalisation of Gretton Thm 7 to m != n):
        2 (sqrt(K/m) + sqrt(K/n)) + sqrt(2 K (m + n) ln(1/alpha) / (m n)).
    unbiased (Hoeffding 1963 sec. 5, two-sample U-statistic, kernel range 4K; Gretton Thm 10):
        sqrt(8 K^2 ln(1/alpha) / k), k = min(floor(m/2), floor(n/2))."""
    K = K_BOUND
    if estimator == "biased":
        return 2.0 * (math.sqrt(K / m) + math.sqrt(K / n)) + math.sqrt(
            2.0 * K * (m + n) * math.log(1.0 / alpha) / (m * n)
        )
    if estimator == "unbiased":
        k = min(m // 2, n // 2)
        return math.sqrt(8.0 * K**2 * math.log(1.0 / alpha) / k)
    raise ValueError(f"unknown estimator {estimator!r}")


def _test(X, Y, kernel, n_bins, alpha, estimator):
    """One MMD two-sample test; H0 (P = Q) rejected iff statistic > threshold (strict)."""
    statistic = literal_mmd(X, Y, kernel, n_bins, estimator)
    threshold = literal_threshold(len(X), len(Y), alpha, estimator)
    return {
        "m": len(X),
        "n": len(Y),
        "statistic": statistic,
        "threshold": threshold,
        "rejected": bool(statistic > threshold),
    }


def _successors(state_runs):
    """{start state s: [s_{t+1} for every transition (s_t = s, s_{t+1}) of every run]};
    transitions pooled over all t (assumption A2, time-homogeneity)."""
    out = {}
    for states in state_runs:
        for t in range(len(states) - 1):
            out.setdefault(tuple(int(v) for v in states[t]), []).append(states[t + 1])
    return out


def literal_compare(
    a_runs, b_runs, bins, kernel, alpha=0.01, estimator="biased", continue_on_start_difference=False
):
    """The process of sec. V-A (Fig. 2, path a): discretize, test start distributions (R1), then
    the successor distribution of every common start state (R2);
    distance = |{s in S : H0 rejected}| / |S| (eq. 6).

    Returns dict: edges; n_states = prod(len(e) + 1); start = {m, n, statistic, threshold, rejected}
    (m, n = numbers of runs); stopped (start rejected and not continue_on_start_difference);
    states = {s: {m, n, statistic, threshold, rejected}} for start states with >= min_samples
    successors in both sets; untestable = sorted other start states; distance (None when stopped).
    min_samples = 1 (biased) or 2 (unbiased). When stopped, no transition is examined: states = {},
    untestable = []."""
    edges = literal_edges(a_runs, b_runs, bins)
    n_bins = [len(e) + 1 for e in edges]
    n_states = int(np.prod(n_bins))
    a_states = [literal_states(np.asarray(r, dtype=float), edges) for r in a_runs]
    b_states = [literal_states(np.asarray(r, dtype=float), edges) for r in b_runs]
    min_samples = 1 if estimator == "biased" else 2

    # R1: start distributions, one sample (the first state) per run.
    X0 = np.array([s[0] for s in a_states], dtype=float)
    Y0 = np.array([s[0] for s in b_states], dtype=float)
    start = _test(X0, Y0, kernel, n_bins, alpha, estimator)
    stopped = start["rejected"] and not continue_on_start_difference
    result = {
        "edges": edges,
        "n_states": n_states,
        "start": start,
        "stopped": stopped,
        "states": {},
        "untestable": [],
        "distance": None,
    }
    if stopped:
        return result

    # R2: one row of the transition matrix per start state s, compared by the same test.
    succ_a, succ_b = _successors(a_states), _successors(b_states)
    untestable = []
    for s in set(succ_a) | set(succ_b):
        X, Y = succ_a.get(s, []), succ_b.get(s, [])
        if len(X) < min_samples or len(Y) < min_samples:
            untestable.append(s)
            continue
        result["states"][s] = _test(
            np.array(X, dtype=float), np.array(Y, dtype=float), kernel, n_bins, alpha, estimator
        )
    result["untestable"] = sorted(untestable)
    rejected = sum(1 for r in result["states"].values() if r["rejected"])
    result["distance"] = rejected / n_states
    return result


def literal_permutation_statistics(X, Y, kernel, n_bins, estimator, assignments):
    """Statistic of literal_mmd for each relabelling of the pooled sample Z = vstack([X, Y]):
    first sample Z[a], second Z[~a]; the bandwidth is recomputed on every permuted split."""
    Z = np.vstack([np.asarray(X, dtype=float), np.asarray(Y, dtype=float)])
    out = []
    for a in assignments:
        a = np.asarray(a, dtype=bool)
        out.append(literal_mmd(Z[a], Z[~a], kernel, n_bins, estimator))
    return np.array(out)
