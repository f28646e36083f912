"""Vision to action (paper section 6.6): trials whose hole estimate comes from the localizer.

    python -m mjx_peg.vision act --model runs/vision/model --policy baseline \
        --shapes circle,square --trials 200 --out runs/vision/act

For each shape, `trials` trials are drawn as the evaluation draws them (task.sample_trials, the
paper's 50 mm, friction 0.2-0.9), with the grasp errors at the paper's maxima: tilt about x and
y uniform in +-12 deg, grasp height uniform in +-30 % of S/2. Each trial then runs on the
C MuJoCo engine with the paper's 60 s limit, three times:

- vision: a randomized bird's-eye render of that trial's true board (the training
  randomization, fresh seeds) goes through the localizer; its estimate (position, yaw, shape,
  size) replaces the sampled localization error: the start above the hole, the controller's goal
  and the policy's observation all come from it;
- sampled: the same trial with the localization error drawn uniformly within +-8 mm / +-12 deg
  (the paper's largest ranges), what the grids assume;
- exact: the same trial with the true hole pose (no localization error): what the grasp errors
  alone leave of the policy's success.

Same boards, grasps, frictions and start heights in all three: paired comparisons (exact McNemar
test on the trials where the two differ). Writes trials.csv, summary.md and summary.json.
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from pathlib import Path

import numpy as np

from mjx_peg import outdir
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.evaluation.stats import mcnemar_p
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.dataset import Renderer, make_label
from mjx_peg.vision.localizer import Localizer
from mjx_peg.vision.metrics import wrapped_yaw_error
from mjx_peg.vision.randomize import sample_view
from mjx_peg.world import kinematics
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.rotations import tool_down_rotation
from mjx_peg.world.task import TaskConfig, TrialSpec, feasible_configuration, sample_trials

RESULT_FILES = ("trials.csv", "summary.json", "summary.md")
PAPER_SUCCESS = 0.92  # section 6.6: 92 % over 200 trials for both circle and square
LOC_MM, LOC_DEG = 8.0, 12.0  # the sampled localization error's ranges
TILT_DEG, GRASP_DZ_FRACTION = 12.0, 0.30  # grasp errors: tilt, height as a fraction of S/2


def draw_trials(shape: str, size: float, count: int, seed: int) -> TrialSpec:
    """`count` trials of one shape: the sampled condition (+-8 mm / +-12 deg localization error,
    grasp tilt +-12 deg, grasp height +-30 % of S/2)."""
    task = TaskConfig(
        shapes=(shape,),
        sizes=(size,),
        linear_error=LOC_MM / 1000.0,
        angular_error=math.radians(LOC_DEG),
    )
    specs = sample_trials(task, np.random.default_rng([seed, SHAPES.index(shape)]), count)
    arrays = specs.to_arrays()
    height_scale = GRASP_DZ_FRACTION * (size / 2.0) / (LOC_MM / 1000.0)  # +-8 mm -> +-30 % S/2
    grasp = arrays["grasp_error"].copy()
    grasp[:, 0] *= height_scale  # the flange model's grasp height; the board model's below
    arrays["grasp_error"] = grasp
    arrays["board_height"] = arrays["board_height"] * height_scale
    return TrialSpec.from_arrays(arrays).validate()


def with_estimates(specs: TrialSpec, est_pos: np.ndarray, est_yaw: np.ndarray):
    """(specs with the hole estimate replaced and the start re-solved above it, ok mask).

    The start keeps its height and lies above the new estimate, tool down at its yaw (the
    task's default: no start jitter); trials with no feasible start configuration are not ok.
    """
    arrays = specs.to_arrays()
    arrays["hole_est_pos"] = np.asarray(est_pos, dtype=np.float64)
    arrays["hole_est_yaw"] = np.asarray(est_yaw, dtype=np.float64)
    arrays["loc_error"] = np.concatenate(
        [
            arrays["hole_est_pos"] - arrays["board_pos"],
            (arrays["hole_est_yaw"] - arrays["board_yaw"])[:, None],
        ],
        axis=1,
    )
    tcp0 = arrays["tcp0_pos"].copy()
    tcp0[:, :2] = arrays["hole_est_pos"]
    rot = tool_down_rotation(arrays["hole_est_yaw"])
    q0, ok = feasible_configuration(tcp0, rot, TaskConfig().max_condition)
    arrays["tcp0_pos"], arrays["tcp0_rot"] = tcp0, rot
    arrays["q0"] = np.where(ok[:, None], kinematics.wrap_angle(np.nan_to_num(q0)), specs.q0)
    return TrialSpec.from_arrays(arrays).validate(), ok


def localize_trials(
    localizer: Localizer, specs: TrialSpec, seed: int, tag: int, progress: bool = True
) -> list[dict]:
    """One localization per trial from a fresh randomized render of its true board."""
    from tqdm import tqdm

    out = []
    with Renderer() as renderer:
        for k in tqdm(
            range(len(specs)),
            desc="render + localize",
            unit="trial",
            disable=not progress,
            dynamic_ncols=True,
        ):
            board = {
                "shape": SHAPES[int(specs.shape_id[k])],
                "size": float(specs.size[k]),
                "x": float(specs.board_pos[k, 0]),
                "y": float(specs.board_pos[k, 1]),
                "yaw": float(specs.board_yaw[k]),
            }
            rng = np.random.default_rng([seed, 7919, tag, k])
            view = sample_view(rng, board, "nominal", renderer.width, renderer.height)
            image = renderer.image(board, view)
            label = make_label(board, view)
            t0 = time.perf_counter()
            result = localizer.localize(image, CameraCalibration.from_json(label["calibration"]))
            out.append({"board": board, "result": result, "latency_s": time.perf_counter() - t0})
    return out


def controller_vectors(
    policy: str, specs: TrialSpec, shapes: list[str], sizes: np.ndarray, hole_scales: np.ndarray
):
    """(B, 38) for trials whose policy observation (in the policy's layout) uses the given
    shapes, sizes and hole scales."""
    if policy == "baseline":
        from mjx_peg.skill.baseline import baseline_params

        return np.tile(baseline_params(), (len(specs), 1))
    from mjx_peg.policy.export import load_policy

    loaded = load_policy(policy)
    obs = loaded.observe(
        np.array([SHAPES.index(s) for s in shapes]),
        np.asarray(sizes, dtype=np.float64),
        np.asarray(hole_scales, dtype=np.float64),
        specs.hole_est_pos,
        specs.hole_est_yaw,
    )
    return loaded.vectors_for(obs)


def run_act(
    localizer: Localizer,
    policy: str,
    out_dir,
    shapes=("circle", "square"),
    size: float = 0.05,
    trials: int = 200,
    seed: int = 0,
    engine_options: dict | None = None,
    progress: bool = True,
    time_limit_s: float = 60.0,
    skill: str | None = None,
) -> dict:
    """Run both conditions for every shape; write trials.csv, summary.json, summary.md. `skill`:
    a named skill (skill.search.SKILLS); None: the policy's (`policy.export.policy_skill`).
    summary.json records the skill's name and every constant."""
    from tqdm import tqdm

    from mjx_peg.engines import run_trials

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from mjx_peg.policy.export import choose_skill

    chosen = choose_skill(skill, policy)
    config = TrialConfig(time_limit_s=time_limit_s, search=chosen.config)
    rows = []
    summary = {
        "policy": policy,
        "skill": chosen.name,
        "skill_constants": chosen.record()["constants"],
        "trials_per_shape": trials,
        "size_mm": size * 1000,
        "seed": seed,
        "time_limit_s": time_limit_s,
        "shapes": {},
    }
    t_all = time.perf_counter()
    for tag, shape in enumerate(shapes):
        sampled = draw_trials(shape, size, trials, seed)
        located = localize_trials(localizer, sampled, seed, tag, progress)
        est = [r["result"].estimate for r in located]
        vision, ok = with_estimates(
            sampled, np.array([[e.x, e.y] for e in est]), np.array([e.yaw for e in est])
        )
        exact, ok_exact = with_estimates(sampled, sampled.board_pos, sampled.board_yaw)
        runs = {}
        for name, specs, shp, siz, fit in (
            ("vision", vision, [e.shape for e in est], [e.size for e in est],
             [e.hole_scale for e in est]),
            ("sampled", sampled, [shape] * trials, sampled.size, sampled.hole_scale),
            ("exact", exact, [shape] * trials, sampled.size, sampled.hole_scale),
        ):  # fmt: skip
            t0 = time.perf_counter()
            params = controller_vectors(policy, specs, shp, np.asarray(siz), np.asarray(fit))
            with tqdm(
                total=len(specs),
                desc=f"{shape} trials, {name}",
                unit="trial",
                disable=not progress,
                dynamic_ncols=True,
            ) as bar:
                result = run_trials(
                    specs,
                    params,
                    engine="mujoco",
                    config=config,
                    progress=bar.update,
                    **(engine_options or {}),
                )
            runs[name] = (result, time.perf_counter() - t0)
        vis_ok = runs["vision"][0].success & ok
        smp_ok = runs["sampled"][0].success
        exact_ok = runs["exact"][0].success & ok_exact
        pos_err = 1000 * np.linalg.norm(vision.hole_est_pos - vision.board_pos, axis=1)
        yaw_err = np.array(
            [
                math.degrees(wrapped_yaw_error(shape, e.yaw, float(y)))
                for e, y in zip(est, vision.board_yaw, strict=True)
            ]
        )
        summary["shapes"][shape] = {
            "vision_success": float(vis_ok.mean()),
            "sampled_success": float(smp_ok.mean()),
            "exact_success": float(exact_ok.mean()),
            "mcnemar_p": mcnemar_p(vis_ok, smp_ok),
            "mcnemar_p_vision_exact": mcnemar_p(vis_ok, exact_ok),
            "no_start_configuration": int((~ok).sum()),
            "shape_accuracy": float(np.mean([e.shape == shape for e in est])),
            "size_accuracy": float(np.mean([abs(e.size - size) < 1e-6 for e in est])),
            "pos_err_mm": {f"p{p}": float(np.percentile(pos_err, p)) for p in (50, 95, 99)},
            "pos_err_max_mm": float(pos_err.max()),
            "yaw_err_deg": (
                {f"p{p}": float(np.nanpercentile(yaw_err, p)) for p in (50, 95, 99)}
                if np.isfinite(yaw_err).any()
                else None
            ),
            "wall_s": {k: round(v[1], 1) for k, v in runs.items()},
            "localize_latency_median_s": float(np.median([r["latency_s"] for r in located])),
        }
        for k in range(trials):
            rv, rs = runs["vision"][0], runs["sampled"][0]
            rows.append(
                {
                    "shape": shape,
                    "trial": k,
                    "board_x": sampled.board_pos[k, 0],
                    "board_y": sampled.board_pos[k, 1],
                    "board_yaw_deg": math.degrees(sampled.board_yaw[k]),
                    "vision_dx_mm": 1000 * vision.loc_error[k, 0],
                    "vision_dy_mm": 1000 * vision.loc_error[k, 1],
                    "vision_yaw_err_deg": yaw_err[k],
                    "vision_shape": est[k].shape,
                    "vision_size_mm": 1000 * est[k].size,
                    "sampled_dx_mm": 1000 * sampled.loc_error[k, 0],
                    "sampled_dy_mm": 1000 * sampled.loc_error[k, 1],
                    "sampled_dyaw_deg": math.degrees(sampled.loc_error[k, 2]),
                    "grasp_dz_mm": 1000 * sampled.grasp_error[k, 0],
                    "grasp_tilt_x_deg": math.degrees(sampled.grasp_error[k, 1]),
                    "grasp_tilt_y_deg": math.degrees(sampled.grasp_error[k, 2]),
                    "friction": sampled.friction[k],
                    "vision_success": bool(vis_ok[k]),
                    "vision_time_s": rv.time_s[k],
                    "sampled_success": bool(rs.success[k]),
                    "sampled_time_s": rs.time_s[k],
                    "exact_success": bool(exact_ok[k]),
                    "exact_time_s": runs["exact"][0].time_s[k],
                }
            )
    vis_all = np.array([r["vision_success"] for r in rows])
    smp_all = np.array([r["sampled_success"] for r in rows])
    exact_all = np.array([r["exact_success"] for r in rows])
    summary["all"] = {
        "vision_success": float(vis_all.mean()),
        "sampled_success": float(smp_all.mean()),
        "exact_success": float(exact_all.mean()),
        "mcnemar_p": mcnemar_p(vis_all, smp_all),
        "mcnemar_p_vision_exact": mcnemar_p(vis_all, exact_all),
        "paper_success": PAPER_SUCCESS,
    }
    summary["wall_s"] = round(time.perf_counter() - t_all, 1)
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    outdir.write_atomic(out / "trials.csv", table.getvalue())
    outdir.write_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    outdir.write_atomic(out / "summary.md", summary_markdown(summary))
    return summary


def summary_markdown(summary: dict) -> str:
    n = summary["trials_per_shape"]
    lines = [
        f"# Vision to action: policy {summary['policy']}, S = {summary['size_mm']:g} mm, "
        f"{n} trials per shape, seed {summary['seed']}",
        "",
        f"Skill: {summary.get('skill', 'paper')}.",
        "",
        f"Grasp errors uniform within +-{TILT_DEG:g} deg tilt and +-{100 * GRASP_DZ_FRACTION:g} % "
        f"of S/2 height (the paper's maxima); {summary['time_limit_s']:g} s limit; C MuJoCo "
        "engine.",
        "",
        "| shape | vision | sampled +-8 mm / +-12 deg | McNemar p | exact pose | McNemar p "
        "| paper (vision) | vision position error p50 / p95 / p99 mm | yaw p50 / p95 / p99 deg "
        "| shape / size acc. |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for shape, s in summary["shapes"].items():
        pos = " / ".join(f"{s['pos_err_mm'][f'p{p}']:.2f}" for p in (50, 95, 99))
        yaw = (
            "-"
            if s["yaw_err_deg"] is None
            else " / ".join(f"{s['yaw_err_deg'][f'p{p}']:.2f}" for p in (50, 95, 99))
        )
        lines.append(
            f"| {shape} | {100 * s['vision_success']:.1f} % | {100 * s['sampled_success']:.1f} % "
            f"| {s['mcnemar_p']:.3g} | {100 * s['exact_success']:.1f} % | "
            f"{s['mcnemar_p_vision_exact']:.3g} | {100 * PAPER_SUCCESS:.0f} % | {pos} | {yaw} | "
            f"{100 * s['shape_accuracy']:.1f} / {100 * s['size_accuracy']:.1f} % |"
        )
    a = summary["all"]
    lines.append(
        f"| all | {100 * a['vision_success']:.1f} % | {100 * a['sampled_success']:.1f} % | "
        f"{a['mcnemar_p']:.3g} | {100 * a['exact_success']:.1f} % | "
        f"{a['mcnemar_p_vision_exact']:.3g} | {100 * PAPER_SUCCESS:.0f} % | | | |"
    )
    lines += [
        "",
        "Success rates of the same trials (board, friction, grasp, start height) with the hole "
        "estimate from the localizer (vision), drawn within +-8 mm / +-12 deg of the truth "
        "(sampled) and exact; McNemar: two-sided exact test on the trials where the two differ, "
        "against vision.",
        "",
        f"Wall time {summary['wall_s']:.0f} s in all.",
    ]
    return "\n".join(lines) + "\n"
