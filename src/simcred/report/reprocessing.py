"""Figures of the reprocessing pipeline (paper 002, [1] Figs. 3-7).

Colours follow [1]: EGO blue, TO green; GT solid, resimulations dashed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simcred.report.figures import plt, save_figure
from simcred.reprocess import output
from simcred.reprocess.decomposition import QUANTITIES, STEPS
from simcred.reprocess.pipeline import LOG_RISK_FLOOR, Reprocessed, log_risk
from simcred.reprocess.representation import GT, SD, Rep, SensorKind
from simcred.reprocess.vary import VariationCampaign, write_campaign

EGO_COLOR, TO_COLOR = "#1f4e9c", "#2ca02c"
RGT, RSD = GT.resimulation(), SD.resimulation()
TRACE_STYLES = {  # representation -> (label, colour, line style)
    GT: ("GT", "#222222", "-"),
    SD: ("SD (no GT recorded)", "#222222", "-"),
    RGT: ("rGT (ideal sensor)", "#1f77b4", "--"),
    RSD: ("rSD (ideal sensor)", "#17becf", "--"),
    GT.resimulation(SensorKind.SCENARIO_BASED): ("rGT (scenario-based sensor)", "#d62728", "-."),
    SD.resimulation(SensorKind.SCENARIO_BASED): ("rSD (scenario-based sensor)", "#ff7f0e", ":"),
}
def _styles(result: Reprocessed) -> list[tuple[Rep, tuple[str, str, str]]]:
    """The representations to draw: the measurement (GT, or SD when there is no GT) and every
    resimulation that was run."""
    reference = GT if GT in result.states else SD
    return [(key, style) for key, style in TRACE_STYLES.items()
            if key.fit() in result.states and (key == reference or key.resimulated)]


UNITS = {"d": "Δd [m]", "v": "Δv [m/s]", "heading": "Δθ [rad]"}


def fig3_fit(result: Reprocessed, path: str | Path, source: str = "GT") -> Path:
    """Fig. 3: the scenario description fitted to ``source`` (thin) over the data (thick)."""
    ego, to = result.config.ego, result.config.objects[0]
    source = Rep(source)
    t, raw, fit = result.times, result.states[source], result.states[source.fit()]
    fig = plt.figure(figsize=(12, 7), constrained_layout=True)
    grid = fig.add_gridspec(2, 2)
    xy, speed, heading = fig.add_subplot(grid[0, :]), fig.add_subplot(grid[1, 0]), \
        fig.add_subplot(grid[1, 1])
    for name, color in ((ego, EGO_COLOR), (to, TO_COLOR)):
        xy.plot(raw[name].x, raw[name].y, color=color, lw=4, alpha=0.35,
                label=f"{name} {source}")
        xy.plot(fit[name].x, fit[name].y, color=color, lw=1, label=f"{name} fit")
        speed.plot(t, raw[name].v, color=color, lw=4, alpha=0.35)
        speed.plot(t, fit[name].v, color=color, lw=1)
        heading.plot(t, np.unwrap(raw[name].heading), color=color, lw=4, alpha=0.35)
        heading.plot(t, fit[name].heading, color=color, lw=1)
    xy.set(xlabel="x [m]", ylabel="y [m]",
           title=f"scenario description fitted to {source} positions (thin) over {source} "
                 "(thick)")
    xy.legend(fontsize=8, ncols=4)
    speed.set(xlabel="t [s]", ylabel="v [m/s]", title="speed (not fitted: follows from x, y)")
    heading.set(xlabel="t [s]", ylabel="θ [rad]", title="heading")
    for ax in (xy, speed, heading):
        ax.grid(alpha=0.3)
    return save_figure(fig, Path(path))


def fig4_errors(result: Reprocessed, path: str | Path, sensor: str = "ideal") -> Path:
    """Fig. 4: error boxes per pipeline step (columns) and quantity (rows), EGO and TO."""
    table = result.errors[sensor]
    steps = [s for s in STEPS if s in table]
    names = (result.config.ego, result.config.objects[0])
    fig, axes = plt.subplots(len(QUANTITIES), 1, figsize=(13, 8.5), constrained_layout=True,
                             sharex=True)
    for ax, quantity in zip(axes, QUANTITIES, strict=True):
        for k, name in enumerate(names):
            boxes = [_box(table[s][name][quantity]) for s in steps]
            positions = np.arange(len(steps)) + (k - 0.5) * 0.36
            color = (EGO_COLOR, TO_COLOR)[k]
            ax.bxp(boxes, positions=positions, widths=0.3, showmeans=False, patch_artist=True,
                   boxprops={"facecolor": color, "alpha": 0.45},
                   medianprops={"color": "black"}, whiskerprops={"color": color},
                   capprops={"color": color}, showfliers=False)
            means = [table[s][name][quantity].mean for s in steps]
            stds = [table[s][name][quantity].std for s in steps]
            ax.errorbar(positions, means, yerr=stds, fmt="D", ms=4, color="black", lw=0.8,
                        label=f"{name}: mean ± std" if quantity == "d" else None)
        ax.set_ylabel(UNITS[quantity])
        ax.set_yscale("symlog", linthresh={"d": 0.01, "v": 0.01, "heading": 0.001}[quantity])
        ax.grid(alpha=0.3, axis="y")
    axes[0].set_ylim(bottom=0)  # Δd is a distance
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    axes[-1].set_xticks(range(len(steps)), [f"Δ{s}" for s in steps])
    title = "errors of the reprocessing pipeline (boxes: quartiles, whiskers: full extent)"
    axes[0].set_title(f"{title} — {sensor} sensor in the resimulation; EGO blue, TO green")
    return save_figure(fig, Path(path))


def _box(stats) -> dict[str, float]:
    return {"med": stats.median, "q1": stats.q25, "q3": stats.q75, "whislo": stats.low,
            "whishi": stats.high}


def fig5_sd_velocity(result: Reprocessed, path: str | Path) -> Path:
    """Fig. 5: the TO's SD speed, its fit, and GT: the fit removes the sensor's delay."""
    to = result.config.objects[0]
    t = result.times
    fig, ax = plt.subplots(figsize=(10, 4.5), constrained_layout=True)
    ax.plot(t, result.states["SD"][to].v, color="#d62728", lw=1, label="SD (object list)")
    ax.plot(t, result.states["fit(SD)"][to].v, color="#ff7f0e", lw=2, ls="--",
            label="fit(SD) (from SD positions)")
    if "GT" in result.states:
        ax.plot(t, result.states["GT"][to].v, color="black", lw=1.2, label="GT")
    ax.set(xlabel="t [s]", ylabel="TO speed [m/s]",
           title="TO speed: the fit of SD positions converges towards GT")
    ax.legend(fontsize=9)
    ax.grid(alpha=0.3)
    return save_figure(fig, Path(path))


def fig6_traces(result: Reprocessed, path: str | Path, before: float = 0.5,
                after: float = 3.5) -> Path:
    """Fig. 6: EGO paths of GT and the resimulations around the first reaction, with the TO.

    [1] shows the last 3 s of its drive; here the window runs from ``before`` seconds before
    the earliest reaction to ``after`` seconds after it (the whole drive if nobody reacts).
    Every path is its scenario description (GT's too), so noise does not hide the difference.
    """
    ego, to = result.config.ego, result.config.objects[0]
    t = result.times
    reacted = [r.time for r in result.reactions.values() if r.time == r.time]
    start = min(reacted) - before if reacted else t[0]
    window = (t >= start) & (t <= start + before + after)
    fig, ax = plt.subplots(figsize=(12, 4.5), constrained_layout=True)
    for key, (label, color, style) in _styles(result):
        states = result.states[key.fit()]
        ax.plot(states[ego].x[window], states[ego].y[window], color=color, ls=style, lw=2,
                label=f"EGO {label}")
    truth = result.states[GT.fit() if GT.fit() in result.states else SD.fit()][to]
    ax.plot(truth.x[window], truth.y[window], color=TO_COLOR, lw=6, alpha=0.35, label="TO")
    ax.set(xlabel="x [m]", ylabel="y [m]",
           title=f"paths from {t[window][0]:.1f} s to {t[window][-1]:.1f} s: who brakes, "
                 "who evades")
    ax.legend(fontsize=8, ncols=2)
    ax.grid(alpha=0.3)
    return save_figure(fig, Path(path))


def fig7_velocity_risk(result: Reprocessed, path: str | Path) -> Path:
    """Fig. 7: EGO speeds of GT and the resimulations (TO for reference) and their risk."""
    ego, to = result.config.ego, result.config.objects[0]
    fig, (speed, risk) = plt.subplots(2, 1, figsize=(10, 7.5), constrained_layout=True,
                                      sharex=True)
    t = result.times
    for key, (label, color, style) in _styles(result):
        source = key.fit() if key.resimulated else key
        speed.plot(t, result.states[source][ego].v, color=color, ls=style,
                   label=f"EGO {label}")
        r = result.risk[key]
        risk.plot(r.t, log_risk(r.risk), color=color, ls=style, label=label)
    if "GT" in result.states:
        speed.plot(t, result.states["GT"][to].v, color=TO_COLOR, lw=0.8, label="TO (GT)")
    _mark_reactions(speed, result)
    speed.set(ylabel="v [m/s]", title="EGO speed: the measurement and its resimulations"
                                      + _shift_title(result))
    risk.set(xlabel="t [s]", ylabel="log10 risk", title="TTR risk per scene (log scale)")
    for ax in (speed, risk):
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    return save_figure(fig, Path(path))


def _mark_reactions(ax, result: Reprocessed) -> None:
    """A marker at each representation's reaction (eqs. (4)-(7)) on its speed curve."""
    ego = result.config.ego
    for key, (_, color, _) in _styles(result):
        reaction = result.reactions.get(key)
        if reaction is None or np.isnan(reaction.time):
            continue
        track = result.descriptions[key.fit()].objects[ego].states(np.array([reaction.time]))
        ax.plot([reaction.time], [track.v[0]], marker="o", ms=6, mfc="none", color=color)


def _shift_title(result: Reprocessed) -> str:
    shift = None if result.analysis is None else result.analysis.ideal.dt_react_gt_rgt
    return "" if shift is None else (f"\n(o: reaction; GT − rGT = {shift:.2f} s, [1] eq. 4: "
                                     "≈ 1 s)")


FIGURES = {"fig3_fit.png": fig3_fit, "fig4_errors.png": fig4_errors,
           "fig5_sd_velocity.png": fig5_sd_velocity, "fig6_traces.png": fig6_traces,
           "fig7_velocity_risk.png": fig7_velocity_risk}


def write_figures(result: Reprocessed, directory: str | Path) -> list[Path]:
    """Every figure that the measurement allows, into ``directory``."""
    directory = Path(directory)
    written = []
    for name, draw in FIGURES.items():
        if "GT" not in result.states and name in ("fig3_fit.png", "fig4_errors.png"):
            source = "SD"
            if name == "fig3_fit.png":
                written.append(fig3_fit(result, directory / name, source))
            continue
        written.append(draw(result, directory / name))
    if "scenario-based" in result.errors:
        written.append(fig4_errors(result, directory / "fig4_errors_scenario_based.png",
                                   "scenario-based"))
    return written


VARIATION_TO, VARIATION_EGO, REFERENCE_COLOR = "#7b3294", "#1f4e9c", "#1a9641"


def fig8_variations(campaign, path: str | Path) -> Path:
    """Fig. 8: TO (purple) and EGO (blue) of every variation against the unvaried resimulation
    (green): paths, speeds, and the distribution of the maximum risk."""
    c, runs = campaign.config, campaign.runs
    fig = plt.figure(figsize=(12, 10), constrained_layout=True)
    grid = fig.add_gridspec(3, 1, height_ratios=[1.1, 1, 1])
    paths, speeds, risks = (fig.add_subplot(grid[i]) for i in range(3))
    for i in range(runs.n_runs):
        run = runs.run(i)
        paths.plot(run[f"{c.to}.x"], run[f"{c.to}.y"], color=VARIATION_TO, lw=0.6, alpha=0.12)
        paths.plot(run[f"{c.ego}.x"], run[f"{c.ego}.y"], color=VARIATION_EGO, lw=0.6, alpha=0.12)
        speeds.plot(run["t"], run[f"{c.to}.v"], color=VARIATION_TO, lw=0.6, alpha=0.12)
        speeds.plot(run["t"], run[f"{c.ego}.v"], color=VARIATION_EGO, lw=0.6, alpha=0.12)
    reference = campaign.reference_runs.run(0)
    for name in (c.to, c.ego):
        paths.plot(reference[f"{name}.x"], reference[f"{name}.y"], color=REFERENCE_COLOR, lw=2)
        speeds.plot(reference["t"], reference[f"{name}.v"], color=REFERENCE_COLOR, lw=2)
    paths.plot([], [], color=VARIATION_TO, label="TO, variations")
    paths.plot([], [], color=VARIATION_EGO, label="EGO, variations")
    paths.plot([], [], color=REFERENCE_COLOR, lw=2, label="unvaried resimulation (rGT)")
    paths.set(xlabel="x [m]", ylabel="y [m]",
              title=f"{runs.n_runs} kept variations of {campaign.variations.generated}: paths")
    paths.legend(fontsize=8, ncols=3)
    speeds.set(xlabel="t [s]", ylabel="v [m/s]", title="speeds (TO purple, EGO blue)")
    values = np.log10(np.maximum(campaign.max_risks, LOG_RISK_FLOOR))
    risks.hist(values, bins=30, color=VARIATION_TO, alpha=0.7, label="variations")
    p5, p95 = np.percentile(values, [5, 95])
    for q, label in ((p5, "5th / 95th percentile"), (p95, None)):
        risks.axvline(q, color="black", ls="--", lw=1, label=label)
    risks.axvline(np.log10(max(campaign.reference.max_risk, LOG_RISK_FLOOR)),
                  color=REFERENCE_COLOR, lw=3, label="rGT")
    risks.set(xlabel="log10 maximum risk", ylabel="variations",
              title="distribution of the maximum TTR risk")
    risks.legend(fontsize=8)
    for ax in (paths, speeds, risks):
        ax.grid(alpha=0.3)
    return save_figure(fig, Path(path))


def write_reprocessed(result: Reprocessed, directory: str | Path) -> dict[str, Path]:
    """:func:`simcred.reprocess.output.write` and Figs. 3-7 into ``directory/figures``."""
    files = output.write(result, directory)
    write_figures(result, Path(directory) / "figures")
    return files


def write_variations(campaign: VariationCampaign, directory: str | Path) -> dict[str, Path]:
    """:func:`simcred.reprocess.vary.write_campaign` and ``figures/fig8_variations.png``."""
    files = write_campaign(campaign, directory)
    files["figure"] = fig8_variations(campaign, Path(directory) / "figures" /
                                      "fig8_variations.png")
    return files
