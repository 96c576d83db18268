"""A drive iteration's figure: the rms error against the target per iteration (with the step's
stop level's reach: the share inside the target's band), the damage ratio rig / road per
iteration, and the target and the last iteration's response overlaid over the compared span."""

from __future__ import annotations

import textwrap

from matplotlib.figure import Figure

from bench.analysis.drive_iteration import IterationResult
from bench.report.axes import new_figure


def drive_iteration_figure(step_run_id: str, results: list[IterationResult]) -> Figure:
    """Three panels from ``results`` (one drive iteration's, in iteration order)."""
    fig, (errors, damage, overlay) = new_figure(3, sharex=False)
    fig.set_size_inches(9, 10)
    fig.subplots_adjust(right=0.9, top=0.92)
    iterations = [r.iteration for r in results]
    last = results[-1]
    errors.semilogy(iterations, [r.rms_error_pct for r in results], "o-", color="tab:blue", label="rms error")
    if last.in_band_pct is not None:
        share = errors.twinx()
        share.plot(iterations, [r.in_band_pct for r in results], "s--", color="tab:green")
        share.set(ylabel="inside the target's 95 % band (%)", ylim=(0, 100))
    lo, hi = last.band_hz
    errors.set(xlabel="iteration", ylabel=f"rms error in {lo:g}-{hi:g} Hz (% of the target's rms)")
    errors.set_xticks(iterations)
    errors.set_title("rms error against the target (circles); share inside its band (squares)", fontsize=9)
    damage.plot(iterations, [r.damage_ratio for r in results], "o-", color="tab:red")
    damage.axhspan(0.9, 1.1, color="0.9")
    damage.axhline(1.0, color="black", lw=0.8)
    damage.set(xlabel="iteration", ylabel="damage ratio rig / road")
    damage.set_xticks(iterations)
    damage.set_title(
        f"rainflow damage of the response over the target's, S-N exponent {last.sn_exponent:g}", fontsize=9
    )
    t = last.traces["t_s"]
    overlay.plot(t, last.traces["target"], color="black", lw=1.4, label="target")
    overlay.plot(
        t, last.traces["response"], color="tab:blue", lw=0.8, label=f"response, iteration {last.iteration}"
    )
    overlay.set(
        xlabel="time from the drive's start (s)", ylabel=f"{last.response.replace('_', ' ')} ({last.unit})"
    )
    overlay.legend(fontsize=8, loc="upper right", frameon=False)
    overlay.set_title(f"target and response in {lo:g}-{hi:g} Hz", fontsize=9)
    fig.suptitle(textwrap.fill(f"{step_run_id}: drive iteration on {last.target_source}", 110), fontsize=9)
    return fig
