"""One insertion on a real UR5e (or its rehearsal): `python -m mjx_peg.robot --robot-ip IP ...`.

    mjx-peg-robot --robot-ip 192.168.1.10 --policy runs/paper --hole 450,-120,30 \
        --shape circle --size 50 --shadow

The plan comes first, and is all `--dry-run` does: the start 60 mm above the board top over the
estimated hole, tool down, and the goal, both checked for reach (IK within the joint limits and
the task sampler's conditioning bound); the DMP's free motion between them. Then, on the arm:
connect (ur_rtde), check the robot (`UR5eArm.check_ready`), move to the start (moveJ; not in
`--shadow`), zero the F/T sensor, and run the skill at 500 Hz until it inserts, settles, stops or
reaches `--time-limit`. `--shadow` reads the arm and computes every torque, and sends nothing:
the arm stays where it is (or where a person guides it in freedrive). `--rehearse` runs the same
path against the simulated UR5e behind ur_rtde's interface (`sim_ur5e.py`), the board exactly at
the hole. Writes `ur5e_run.csv` (a row per command period), `ur5e_run.png` and `ur5e_skill.json`
(the skill it ran, every constant) under --out.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from mjx_peg import cli, outdir
from mjx_peg.engines.trial import TrialConfig, as_controller_params, fitted_basis
from mjx_peg.errors import UsageError, shown_path
from mjx_peg.outdir import write_json
from mjx_peg.policy.export import choose_skill, load_policy
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.robot.runtime import HoleEstimate, SkillRun, SkillRuntime, controller_vector, run_skill
from mjx_peg.robot.ur5e import PERIOD_S, UR5eArm, UR5eStop, Workspace, connect
from mjx_peg.skill import dmp
from mjx_peg.skill.control_step import start_state
from mjx_peg.world import constants
from mjx_peg.world.parts import fit_text, hole_scale_of, parse_hole_scale
from mjx_peg.world.task import TaskConfig, feasible_configuration, goal_pose

START_HEIGHT = 0.06  # m: the tip's start above the board top (the sampler's 40-80 mm, centred)
MOVE_SPEED, MOVE_ACCEL = 0.25, 0.5  # rad/s, rad/s^2: moveJ to the start
WATCHDOG_HZ = 100.0  # ur_rtde's watchdog: the script stops if no command comes for 10 ms
RUN_CSV, RUN_PNG = "ur5e_run.csv", "ur5e_run.png"
RUN_SKILL = "ur5e_skill.json"  # the skill the run ran: {"name", "constants"}


def parse_hole(text: str) -> tuple[float, float, float]:
    """'X,Y,YAW' (mm, mm, deg) -> (x, y, yaw) in m, m, rad."""
    parts = text.split(",")
    try:
        x, y, yaw = (float(p) for p in parts)
    except ValueError:
        raise UsageError(f"--hole must be X,Y,YAW in mm, mm, deg, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise UsageError(f"--hole must be finite numbers, got {text!r}")
    return x / 1000.0, y / 1000.0, math.radians(yaw)


def check_trained_for(policy, shape: str, size_mm: float, flag: str = "--policy") -> None:
    """UsageError unless the loaded `policy` was trained on `shape` and at a size S within the
    sizes it was trained at (its manifest's config.shapes and config.size_mm): the arm runs only
    a part the policy has learned."""
    name = flag
    if not policy.shapes or not policy.sizes_mm:
        raise UsageError(f"{name} does not record the shapes and sizes it was trained on")
    if shape not in policy.shapes:
        raise UsageError(
            f"{name} was trained on {', '.join(policy.shapes)}, not {shape}: transfer it first "
            "(train.py --preset transfer --init-from ...)"
        )
    lo, hi = min(policy.sizes_mm), max(policy.sizes_mm)
    if not lo - 1e-6 <= size_mm <= hi + 1e-6:
        trained = f"{lo:g} mm" if lo == hi else f"{lo:g}-{hi:g} mm"
        raise UsageError(
            f"{name} was trained at S = {trained}, not {size_mm:g} mm: train it at that size first"
        )


def plan(hole: HoleEstimate, vector: np.ndarray, config: TrialConfig) -> dict:
    """The insertion's plan: start and goal tcp poses and configurations, the DMP's free motion
    (t, tcp positions in the world frame) from start to goal. ValueError if out of reach."""
    goal_pos, goal_rot = goal_pose(np.array([hole.x, hole.y]), np.array(hole.yaw))
    start_pos = np.array([hole.x, hole.y, constants.HOLE_DEPTH + START_HEIGHT])
    bound = TaskConfig().max_condition
    q_start, ok_start = feasible_configuration(start_pos, goal_rot, bound)
    q_goal, ok_goal = feasible_configuration(goal_pos, goal_rot, bound)
    where = f"the hole at ({1000 * hole.x:.0f}, {1000 * hole.y:.0f}) mm"
    if not (bool(ok_start) and bool(ok_goal)):
        raise UsageError(
            f"{where} is out of the UR5e's reach with the tool down (no IK within the joint "
            f"limits and condition number {bound:g}, at the start 60 mm above it or at the goal)"
        )
    params = as_controller_params(vector, 1)
    k_y = dmp.stiffness_diag(params.k_t, params.k_theta)[0]
    y0 = start_state(goal_pos, goal_rot, start_pos, goal_rot)
    movement = config.movement
    t, y, _ = dmp.rollout(y0, np.zeros(6), k_y, movement, fitted_basis(movement).weights)
    path = goal_pos + y[:, :3] @ goal_rot.T
    return dict(
        start_pos=start_pos,
        goal_pos=goal_pos,
        rot=goal_rot,
        q_start=q_start,
        q_goal=q_goal,
        t=t,
        path=path,
    )


def print_plan(p: dict, hole: HoleEstimate, every_s: float = 0.25) -> None:
    def mm(v):
        return "(" + ", ".join(f"{1000 * c:.1f}" for c in v) + ") mm"

    deg = ", ".join(f"{math.degrees(v):.1f}" for v in p["q_start"])
    print(
        f"plan for the {hole.shape} {1000 * hole.size:g} mm hole"
        f"{fit_text(hole.shape, hole.hole_scale)} at {mm([hole.x, hole.y])}, "
        f"yaw {math.degrees(hole.yaw):.1f} deg:"
    )
    print(f"  move (moveJ) to the start {mm(p['start_pos'])}, tool down: q = ({deg}) deg")
    print(f"  free motion of the DMP to the goal {mm(p['goal_pos'])} (tcp, world frame):")
    step = max(1, round(every_s / (p["t"][1] - p["t"][0])))
    for t, x in zip(p["t"][::step], p["path"][::step], strict=True):
        print(f"    t = {t:5.2f} s  tcp {mm(x)}")


def rehearsal_robot(hole: HoleEstimate, q_start, seed: int):
    """A simulated UR5e at the plan's start, the board exactly at the hole (no error)."""
    from mjx_peg.robot.sim_arm import SimArm
    from mjx_peg.robot.sim_ur5e import SimulatedUR5e
    from mjx_peg.world.rotations import tool_down_rotation
    from mjx_peg.world.task import TrialSpec

    rng = np.random.default_rng(seed)
    one = lambda *v: np.array([v], dtype=np.float64)  # noqa: E731
    start = np.array([[hole.x, hole.y, constants.HOLE_DEPTH + START_HEIGHT]])
    spec = TrialSpec.from_arrays(
        dict(
            shape_id=[constants.SHAPES.index(hole.shape)],
            size=[hole.size],
            hole_scale=[hole.hole_scale],
            board_pos=one(hole.x, hole.y),
            board_yaw=[hole.yaw],
            friction=[0.5],
            loc_error=np.zeros((1, 3)),
            grasp_error=np.zeros((1, 3)),
            board_height=[0.0],
            board_tilt=np.zeros((1, 2)),
            hole_est_pos=one(hole.x, hole.y),
            hole_est_yaw=[hole.yaw],
            tcp0_pos=start,
            tcp0_rot=tool_down_rotation(np.array([hole.yaw])),
            q0=np.asarray(q_start)[None],
            linear_range=[0.0],
            angular_range=[0.0],
            sensor_seed=rng.integers(0, 2**32, 1, dtype=np.uint32),
            sensor_cutoff_scale=[1.0],
            sensor_noise_scale=[1.0],
            sensor_delay_offset=[0],
        )
    ).validate()
    return SimulatedUR5e(SimArm(spec, 0))


def write_log(path: Path, arm: UR5eArm, run: SkillRun, runtime: SkillRuntime) -> int:
    """One row per command period (atomically); returns the row count."""
    n = run.commands
    log = {k: np.asarray(v, dtype=np.float64) for k, v in arm.log.items()}
    shift = np.array(
        [dmp.compliance_offset(runtime.params.compliance, w)[:3] for w in run.log["wrench"]]
    ).reshape(n, 3)
    goal = runtime.goal_pos[0] + shift @ runtime.goal_rot[0].T
    header = (
        ["t_s", "period_ms", "work_ms"]
        + [f"q{i}" for i in range(1, 7)]
        + ["tcp_x", "tcp_y", "tcp_z"]
        + [f"ur_{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")]
        + [f"wrench_{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")]
        + ["goal_x", "goal_y", "goal_z"]
        + [f"tau{i}" for i in range(1, 7)]
        + ["sent"]
    )
    columns = [
        run.log["t"][:, None],
        1000 * log["period_s"][:n, None],
        1000 * log["work_s"][:n, None],
        log["q"][:n],
        run.log["tcp_pos"],
        log["ur_wrench"][:n],
        run.log["wrench"],
        goal,
        run.log["torque"],
        log["sent"][:n, None],
    ]
    table = np.concatenate([c.reshape(n, -1) for c in columns], axis=1)

    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            w.writerows([f"{v:.6g}" for v in row] for row in table)

    outdir.write_atomic(path, write)
    return n


def plot_log(path: Path, arm: UR5eArm, run: SkillRun, hole: HoleEstimate) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n, t = run.commands, run.log["t"]
    tcp, w = run.log["tcp_pos"], run.log["wrench"]
    fig, ax = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    ax[0].plot(t, 1000 * tcp[:, 2], label="tcp height")
    ax[0].plot(
        t, 1000 * np.hypot(tcp[:, 0] - hole.x, tcp[:, 1] - hole.y), label="off the hole axis"
    )
    ax[0].set_ylabel("mm")
    for i, c in enumerate("xyz"):
        ax[1].plot(t, w[:, i], label=f"F{c}")
    ax[1].set_ylabel("sensed force, N")
    ax[2].plot(t, run.log["torque"])
    ax[2].set_ylabel("torque u, N m")
    ax[3].plot(t, 1000 * np.asarray(arm.log["period_s"][:n]), ".", ms=2, label="period")
    ax[3].plot(t, 1000 * np.asarray(arm.log["work_s"][:n]), ".", ms=2, label="work")
    ax[3].axhline(1000 * PERIOD_S, color="k", lw=0.5)
    ax[3].set_ylabel("ms")
    ax[3].set_xlabel("t (s)")
    for a in (ax[0], ax[1], ax[3]):
        a.legend(loc="upper right", fontsize=8)
    mode = "shadow" if arm.shadow else "commanded"
    ax[0].set_title(
        f"UR5e, {mode}: {'inserted' if run.success else run.stopped or 'not inserted'}"
        f" at {run.time_s:.2f} s"
    )
    fig.tight_layout()
    outdir.write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=90))
    plt.close(fig)


def timing(arm: UR5eArm, n: int) -> str:
    period = 1000 * np.asarray(arm.log["period_s"][1:n], dtype=np.float64)
    work = 1000 * np.asarray(arm.log["work_s"][:n], dtype=np.float64)
    if period.size == 0:
        return "no periods"
    p50, p99, pmax = np.percentile(period, [50, 99, 100])
    w50, w99, wmax = np.percentile(work, [50, 99, 100])
    return (
        f"period p50 / p99 / max {p50:.3f} / {p99:.3f} / {pmax:.3f} ms, work {w50:.3f} / "
        f"{w99:.3f} / {wmax:.3f} ms, {arm.missed} missed"
    )


def run(args, prog: str) -> int:
    """The real-arm path of `python -m mjx_peg.robot` (flags parsed there)."""
    if args.command_hz != 1.0 / PERIOD_S:
        raise UsageError(
            "--robot-ip runs direct torque control at the UR5e's 500 Hz only: "
            "leave --command-hz at 500"
        )
    x, y, yaw = parse_hole(args.hole)
    scale = hole_scale_of(args.shape, parse_hole_scale(args.hole_scale))
    hole = HoleEstimate(x, y, yaw, args.shape, args.size / 1000.0, scale,
                        math.radians(args.angular_deg))  # fmt: skip
    given, args.policy = args.policy, resolve_policy(args.policy)
    policy = args.policy
    if policy != "baseline":
        policy = load_policy(policy)
        check_trained_for(policy, args.shape, args.size, f"--policy {shown_path(given)}")
    vector = controller_vector(policy, hole)
    skill = choose_skill(args.skill, policy, args.skill_constant or ())
    config = TrialConfig(time_limit_s=args.time_limit, search=skill.config)
    p = plan(hole, vector, config)
    if args.dry_run:
        print_plan(p, hole)
        print(f"{prog}: dry run: nothing was connected or moved")
        return 0
    outdir.check_apart(args.out, {"--policy": args.policy})
    with outdir.exclusive(args.out):
        return _on_the_arm(args, prog, hole, vector, skill, config, p)


def _on_the_arm(args, prog, hole: HoleEstimate, vector, skill, config: TrialConfig, p) -> int:
    """Connect, check, move and run the skill; the log into --out (held)."""
    paths = [args.out / RUN_CSV, args.out / RUN_PNG, args.out / RUN_SKILL]
    if not args.force:  # an earlier run is kept: refused before the robot is touched
        outdir.refuse_or_move(paths, False)
    if args.rehearse:
        robot = rehearsal_robot(hole, p["q_start"], args.seed)
        interfaces, clock, where = (
            (robot.control, robot.receive, robot.dashboard),
            robot.clock,
            "sim",
        )
    else:
        interfaces, clock, where = connect(args.robot_ip), None, args.robot_ip
    control = interfaces[0]
    if args.model == "controller":
        from mjx_peg.robot.arm_model import ControllerArmModel

        model = ControllerArmModel(control)
    else:
        from mjx_peg.robot.arm_model import MujocoArmModel

        model = MujocoArmModel(args.shape, args.size / 1000.0)
    top = constants.HOLE_DEPTH + START_HEIGHT + 0.05
    arm = UR5eArm(
        *interfaces,
        model,
        workspace=Workspace.around(hole.x, hole.y, top),
        shadow=args.shadow,
        friction_comp=args.friction_comp,
        **({"clock": clock} if clock else {}),
    )
    arm.check_ready()
    # the robot is ready: --out is made, then it moves
    outdir.refuse_or_move(paths, args.force, lambda text: cli.note(prog, text))
    outdir.prepare_dir(args.out)
    write_json(paths[2], skill.record())
    if not args.shadow:
        control.moveJ([float(v) for v in p["q_start"]], MOVE_SPEED, MOVE_ACCEL)
        control.zeroFtSensor()
        control.setWatchdog(WATCHDOG_HZ)
    runtime = SkillRuntime(vector, hole, config)
    try:
        result = run_skill(arm, runtime)
    finally:
        arm.hold()
    rows = write_log(paths[0], arm, result, runtime)
    plot_log(paths[1], arm, result, hole)
    if not args.rehearse:
        arm.close()
    outcome = "inserted" if result.success else "not inserted"
    stop = f", stopped: {result.stopped}" if result.stopped else ""
    sent = "shadow: nothing sent" if args.shadow else f"{arm.commands} torque commands"
    print(
        f"{args.policy} on the UR5e at {where} ({sent}): "
        f"{outcome} at {result.time_s:.2f} s{stop}; peak sensed force {result.peak_force:.0f} N; "
        f"{timing(arm, rows)}; wrote {paths[0]} ({rows} rows) and {paths[1]}"
    )
    adapter_stop = result.stopped and result.stopped != "settled"
    return 1 if adapter_stop else 0


__all__ = ["UR5eStop", "check_trained_for", "parse_hole", "plan", "run"]
