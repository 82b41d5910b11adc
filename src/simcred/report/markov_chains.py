"""Figures of the paper 000 experiments: Fig. 5 (inputs and paths), Figs. 6/7 (distance vs λ)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simcred.report.figures import plt, save_figure

KERNEL_COLORS = {"gaussian": "#1f77b4", "laplace": "#d62728", "linear": "#2ca02c"}


def fig5_inputs(path: str | Path, base_inputs, sample_paths, taus=(0.81, 1.0, 1.2),
                duration: float = 40.0) -> Path:
    """Fig. 5: the time-scaled input functions, and a few resulting paths.

    ``base_inputs(t) -> (speed, steering_rate)`` are the sweep's input functions (the experiment
    gives them: report does not import experiments).
    """
    fig, (speed_ax, steer_ax, path_ax) = plt.subplots(1, 3, figsize=(15, 4.2),
                                                      constrained_layout=True)
    t = np.linspace(0.0, duration, 800)
    for tau in taus:
        speed, steering_rate = base_inputs(tau * t)
        speed_ax.plot(t, tau * speed, label=f"τ = {tau}")
        steer_ax.plot(t, tau * steering_rate, label=f"τ = {tau}")
    speed_ax.set(xlabel="t [s]", ylabel="u_v [m/s]", title="speed input τ·v(τt)")
    steer_ax.set(xlabel="t [s]", ylabel="u_φ̇ [rad/s]", title="steering-speed input τ·w(τt)")
    for ax in (speed_ax, steer_ax):
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    for label, traces in sample_paths:
        for i in range(min(traces.n_runs, 5)):
            run = traces.run(i)
            path_ax.plot(run["x"], run["y"], lw=1, alpha=0.8,
                         color="#1f77b4" if label == "λ = 1.0" else "#d62728",
                         label=label if i == 0 else None)
    path_ax.set(xlabel="x [m]", ylabel="y [m]", title="paths: same shape, shifted start")
    path_ax.set_aspect("equal", adjustable="datalim")
    path_ax.legend(fontsize=8)
    path_ax.grid(alpha=0.3)
    return save_figure(fig, Path(path))


def fig_distance_curves(result, features: str, path: str | Path, title: str) -> Path:
    """Figs. 6/7: distance to the λ = 1 baseline per λ, one panel per test, one line per kernel."""
    lambdas = np.asarray(result.config.lambdas)
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.4), constrained_layout=True)
    for ax, test in zip(axes, ("bound", "permutation"), strict=True):
        for kernel, color in KERNEL_COLORS.items():
            curve = 100 * result.curve(features, test, kernel)
            ax.plot(lambdas, curve, "o-", ms=3, color=color, label=kernel)
        ax.axvline(1.0, color="grey", lw=0.8, ls=":")
        label = "paper's bound test" if test == "bound" else "permutation test"
        ax.set(xlabel="λ (baseline: λ = 1.0)", ylabel="distance [% of |S|]",
               title=f"{label}, α = {result.config.alpha}")
        ax.grid(alpha=0.3)
        ax.legend(title="kernel", fontsize=8)
    c = result.config
    fig.suptitle(f"{title} — {c.runs} runs per λ, sample period {c.dt} s, {c.bins} bins",
                 fontsize=11)
    return save_figure(fig, Path(path))
