"""The report of a finished evaluation: grid.csv, the heatmaps and summary.md.

    write_outputs(out, config, label, paper_name)   # after `runner.run_evaluation`

grid.csv holds one row per range (`grid_table.GridTable`), the heatmaps the success rate and mean
time per range like the paper's Figs. 6-7 (`plots`), summary.md the evaluation's description,
its quarters beside the paper's and the tests (`summary`), and the failure taxonomy of every trial
(`taxonomy`); paper_comparison.png the quarters beside the paper's where it has the condition.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mjx_peg import outdir
from mjx_peg.engines.trial import (
    CHATTER_LIMIT_N,
    CHATTER_MIN_TIME_S,
    TrialConfig,
    chatter_counted,
    smooth_pct,
)
from mjx_peg.evaluation import eval_dir
from mjx_peg.evaluation.config import EvalConfig, range_specs
from mjx_peg.evaluation.grid_table import GridTable
from mjx_peg.evaluation.paper_tables import PAPER
from mjx_peg.evaluation.summary import summary_markdown
from mjx_peg.skill.search import constants_set, skill_description
from mjx_peg.world.constants import HOLE_FITS
from mjx_peg.world.task import SHAPES, TrialSpec

GRASP_DESCRIPTION = {
    "board": "the board's height and tilt about its hole's entrance (the paper's model)",
    "flange": "the peg's height and tilt in the flange (--grasp-model flange, harder than the "
    "paper's)",
}


def _header(out: Path, config: EvalConfig, grid: GridTable, policy_label: str) -> list[str]:
    """summary.md's lines that say what was evaluated and how all its trials went."""
    per_shape = {s: [0, 0] for s in config.shapes}
    steps = settled = 0
    contact = {k: [] for k in ("peak_force", "chatter", "protective_stop", "time_s")}
    for i in range(len(config.ranges)):
        arrays = eval_dir.load_range(out, config, i)
        steps += int(arrays["steps"].sum())
        settled += int(arrays["settled"].sum())
        for k in contact:
            if k in arrays:  # evaluations from before the sensor pipeline lack them
                contact[k].append(arrays[k])
        for s in config.shapes:
            mine = arrays["shape_id"] == SHAPES.index(s)
            per_shape[s][0] += int(arrays["success"][mine].sum())
            per_shape[s][1] += int(mine.sum())
    total, ok = int(grid.trials.sum()), int(grid.successes.sum())
    shapes = ", ".join(
        f"{s} {100.0 * k / max(n, 1):.1f} % of {n}" for s, (k, n) in per_shape.items()
    )
    lin, ang = config.linear_mm, config.angular_deg
    return [
        f"policy: {policy_label}",
        f"grid: {config.grid}, {len(lin)} linear x {len(ang)} angular = {len(config.ranges)} "
        f"ranges; linear +-{lin[0]:g}..{lin[-1]:g} mm, angular +-{ang[0]:g}..{ang[-1]:g} deg",
        f"shapes: {', '.join(config.shapes)} (trials split evenly); size S = {config.size_mm:g} mm"
        f"; hole scale (hole size / peg size) {_fit(config.hole_scale)}",
        f"trials per range: {config.trials}; time limit {config.time_limit_s:g} s per trial; "
        + (
            "every failure ran to the time limit (--full-time-limit)"
            if config.full_time_limit
            else f"{settled} failures ended early, settled (TrialConfig.end_settled)"
        ),
        f"grasp errors: {GRASP_DESCRIPTION[config.grasp_model]}",
        f"skill: {config.skill} ({skill_description(config.skill)}; "
        + "".join(f"{c} set; " for c in constants_set(config.skill, config.skill_constants))
        + f"its constants in {eval_dir.CONFIG_FILE})",
        f"seed {config.seed}; engine {config.engine}",
        f"all trials: {ok} / {total} succeeded ({100.0 * ok / max(total, 1):.2f} %); per shape: "
        + shapes,
        f"simulated: {steps} physics steps = {steps * TrialConfig().timestep:.0f} s",
    ] + _contact_lines({k: np.concatenate(v) for k, v in contact.items() if v})


def _fit(hole_scale) -> str:
    """An evaluation's hole scale in words."""
    if hole_scale is None:
        return "the paper's (circle 1.03 D, shapes with corners 1.08 S)"
    if isinstance(hole_scale, str):
        return f"{hole_scale} ({', '.join(f'{k} {v:g}' for k, v in HOLE_FITS[hole_scale].items())})"
    return f"{hole_scale:g} for every shape"


def _contact_lines(arrays: dict[str, np.ndarray]) -> list[str]:
    """The contact metrics of all trials (TrialResult.contact_summary), if they were recorded."""
    if not {"peak_force", "chatter", "protective_stop", "time_s"} <= set(arrays):
        return []
    n = arrays["peak_force"].size
    long = arrays["chatter"][chatter_counted(arrays["time_s"])]
    p50, p99 = np.percentile(arrays["peak_force"], [50, 99])
    return [
        f"contact: peak sensed force median {p50:.0f} N, p99 {p99:.0f} N; protective stops "
        f"{int(arrays['protective_stop'].sum())} ({100.0 * arrays['protective_stop'].mean():.1f} "
        f"%); chatter (mean |dF| of the axial force over a trial's last second) under "
        f"{CHATTER_LIMIT_N:g} N in "
        f"{smooth_pct(long):.1f} % of the "
        f"{long.size} trials longer than {CHATTER_MIN_TIME_S:g} s, median "
        f"{np.median(long) if long.size else math.nan:.2f} N (of {n} trials)"
    ]


def write_outputs(
    out_dir,
    config: EvalConfig,
    policy_label: str,
    paper_name: str | None,
    other: GridTable | None = None,
    other_name: str = "",
    alternative: str = "less",
) -> GridTable:
    """grid.csv, the two heatmaps, summary.md and (with a paper condition) the paper
    comparison plot of a finished evaluation."""
    from mjx_peg.evaluation import plots

    out = Path(out_dir)
    grid = eval_dir.grid_table(out, config)
    outdir.write_atomic(out / eval_dir.GRID_FILE, grid.csv_text())
    what = f"{', '.join(config.shapes)}, S = {config.size_mm:g} mm, N = {config.trials}"
    plots.success_heatmap(grid, out / eval_dir.SUCCESS_PNG, f"Success rate (%): {what}")
    plots.time_heatmap(grid, out / eval_dir.TIME_PNG, f"Mean time to complete (s): {what}")
    if paper_name is not None:
        paper = PAPER[paper_name]
        plots.paper_bars(grid, paper, out / eval_dir.PAPER_PNG, f"{what}; paper: {paper.title}")
    header = _header(out, config, grid, policy_label)
    text = summary_markdown(grid, header, paper_name, other, other_name, alternative)
    outdir.write_atomic(out / eval_dir.SUMMARY_FILE, text + _failures_section(out, config))
    return grid


def _failures_section(out: Path, config: EvalConfig) -> str:
    """summary.md's failure taxonomy over every trial of the grid (`taxonomy`), if the ranges
    recorded where each tip ended."""
    from mjx_peg.evaluation import taxonomy

    specs, arrays = [], []
    for i in range(len(config.ranges)):
        saved = eval_dir.load_range(out, config, i)
        if eval_dir.TIP_FIELD not in saved:
            return ""
        specs.append(range_specs(config, i))
        arrays.append(saved)
    fields = ("success", "unstable", "protective_stop", "settled", "steps", eval_dir.TIP_FIELD)
    merged = {k: np.concatenate([a[k] for a in arrays]) for k in fields}
    trial = config.trial_config()
    rows = taxonomy.table(TrialSpec.concat(specs), merged, trial.time_limit_s, trial.timestep)
    return "\n## Failures\n\n" + taxonomy.markdown(rows, merged["success"].size)
