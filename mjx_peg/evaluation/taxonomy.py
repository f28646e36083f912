"""Why trials fail: every failed trial in one class, from how it ended and where its tip ended.

How it ended decides first: a protective stop, then unstable physics. Otherwise the tip's end,
measured at the true hole's entrance (`task.hole_frame`: depth along the hole axis below the
entrance, distance from the axis), places it:

- wedged in the hole: more than WEDGED_DEPTH below the entrance, within the hole (jammed);
- above the board: more than ABOVE_HEIGHT above the entrance plane (it never came down, or left:
  the spiral skill withdraws a peg whose search ran out, `SkillConfig.search_budget`);
- on the rim: at the board top with the peg's footprint over the hole's edge (the tip within the
  hole's inradius plus the peg's circumradius of the axis);
- crept away: at the board top, the footprint clear of the hole.

Each class also counts the failures that were still moving when the time limit came (neither
settled nor stopped): slow progress rather than a stuck peg.
"""

from __future__ import annotations

import math

import numpy as np

from mjx_peg.world import parts
from mjx_peg.world.constants import CIRCUMRADIUS, HOLE_DEPTH, SHAPES
from mjx_peg.world.task import TrialSpec, hole_frame

CLASSES = ("protective stop", "unstable", "wedged in the hole", "on the rim", "crept away",
           "above the board")  # fmt: skip
WEDGED_DEPTH = 0.002  # m below the entrance: the tip is in the hole
ABOVE_HEIGHT = 0.005  # m above the entrance plane: the tip is off the board


def tip_at_hole(specs: TrialSpec, tip_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(depth (B,), lateral (B,)) in m: the tip below the true hole's entrance along its axis,
    and its distance from the axis."""
    origin, axis = hole_frame(specs)
    offset = np.asarray(tip_pos, dtype=np.float64) - (origin + HOLE_DEPTH * axis)
    along = np.sum(offset * axis, axis=-1)
    return -along, np.linalg.norm(offset - along[:, None] * axis, axis=-1)


def classify(specs: TrialSpec, arrays) -> np.ndarray:
    """(B,) int: CLASSES index of each failed trial, -1 for a success.

    arrays: TrialResult fields (success, protective_stop, unstable, final_tip_pos) of `specs`.
    """
    depth, lateral = tip_at_hole(specs, arrays["final_tip_pos"])
    names = [SHAPES[int(i)] for i in specs.shape_id]
    size = np.asarray(specs.size, dtype=np.float64)
    hole = np.array([
        parts.hole_inradius(s, float(z), float(h))
        for s, z, h in zip(names, size, specs.hole_scale, strict=True)
    ])  # fmt: skip
    rim = hole + size * np.array([CIRCUMRADIUS[s] for s in names])
    below = depth > WEDGED_DEPTH
    where = np.select(
        [below & (lateral < hole + WEDGED_DEPTH), below, depth < -ABOVE_HEIGHT, lateral < rim],
        [2, 4, 5, 3],  # below the entrance away from the hole: off the board's edge
        default=4,
    )
    label = np.where(arrays["unstable"], 1, where)
    label = np.where(arrays["protective_stop"], 0, label)
    return np.where(arrays["success"], -1, label).astype(np.int64)


def still_moving(arrays, time_limit_s: float, timestep: float) -> np.ndarray:
    """(B,) bool: failures that ran to the time limit without settling or stopping."""
    ran_out = np.asarray(arrays["steps"]) >= int(round(time_limit_s / timestep))
    ended = arrays["settled"] | arrays["protective_stop"] | arrays["unstable"]
    return ~arrays["success"] & ran_out & ~ended


def table(specs: TrialSpec, arrays, time_limit_s: float, timestep: float) -> list[dict]:
    """One row per class: failures, share of all trials, still moving, the tip's end (median)."""
    label = classify(specs, arrays)
    moving = still_moving(arrays, time_limit_s, timestep)
    depth, lateral = tip_at_hole(specs, arrays["final_tip_pos"])
    rows = []
    for k, name in enumerate(CLASSES):
        mine = label == k
        count = int(mine.sum())
        rows.append(
            dict(
                failure=name,
                trials=count,
                share_pct=100.0 * count / max(label.size, 1),
                still_moving=int((mine & moving).sum()),
                lateral_mm=float(np.median(lateral[mine]) * 1e3) if count else math.nan,
                depth_mm=float(np.median(depth[mine]) * 1e3) if count else math.nan,
            )
        )
    return rows


def markdown(rows: list[dict], total: int) -> str:
    """The table of `table` as Markdown, over `total` trials."""
    failed = sum(r["trials"] for r in rows)
    lines = [
        f"{failed} of {total} trials failed. Tip at the end (median): distance from the true "
        "hole axis, depth below its entrance (negative: above).",
        "",
        "| failure | trials | % of all trials | still moving at the limit | tip from axis (mm) "
        "| tip depth (mm) |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        if r["trials"]:
            lines.append(
                f"| {r['failure']} | {r['trials']} | {r['share_pct']:.1f} | {r['still_moving']} "
                f"| {r['lateral_mm']:.1f} | {r['depth_mm']:.1f} |"
            )
    return "\n".join(lines) + "\n"
