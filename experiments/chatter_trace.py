"""Where a trial's chatter comes from: one trial of an evaluation replayed, its true axial force
against what the compliance sees (docs/design/rim_chatter.md).

    python experiments/chatter_trace.py --eval docs/eval/paper_spiral_50mm_small_board \\
        --range 71 --trial 4 [--contacts-at 59.0] [--search 'NAME=V;...'] [--npz F]

The chatter metric (`engines.trial.chatter_of`) is the mean |F_k - F_(k-1)| of the true axial
contact force over the trial's last second. Printed for that second: the metric; the periods
whose axial force falls below a quarter of its median (the contact let go for a period); the
largest lines of the force's spectrum; the same mean step of the axial force the compliance acts
on (after the F/T pipeline and the compliance damping) and its standard deviation; the tcp's
vertical vibration (its height less a 50 ms moving mean, rms); the tip's distance from the true
hole axis. --contacts-at T lists the peg's contacts (geom, distance, normal force) for the 40
periods from T seconds on.
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
from contact import search_changes  # experiments/contact.py

from mjx_peg.engines import mujoco as engine
from mjx_peg.engines.trial import as_controller_params
from mjx_peg.evaluation import demo_cli


def replay(args) -> tuple[dict, dict]:
    """(per-period trace, the hole's frame) of the trial, and the contacts asked for."""
    spec_args = argparse.Namespace(replay=args.eval, range=args.range, trial=args.trial,
                                   **dict.fromkeys(demo_cli._DEFAULTS))  # fmt: skip
    specs, params, config, text, recorded = demo_cli.trial_from_eval(spec_args)
    print(text, "- recorded:", "success" if recorded["success"] else "failure",
          f"after {float(recorded['time_s']):.3f} s")  # fmt: skip
    trace = {k: [] for k in ("axial", "sensed", "tcp", "tip")}
    contacts = []
    first = None if args.contacts_at is None else int(round(args.contacts_at / config.timestep))

    def observe(lane, rows, wrench):
        # lane.state is the state before this period: its axial force is the last period's.
        trace["axial"].append(float(lane.state.axial[0]))
        trace["sensed"].append(float(wrench[0, 2]))
        trace["tcp"].append(lane.tcp_pos[0].copy())
        trace["tip"].append(lane.tip_pos[0].copy())
        step = int(lane.state.step[0])
        if first is not None and first <= step < first + 40:
            m, d, _ = lane.scenes[0].current(int(lane.sim[0]))
            found = []
            for i in range(d.ncon):
                force = np.zeros(6)
                mujoco.mj_contactForce(m, d, i, force)
                names = (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
                         for g in (d.contact[i].geom1, d.contact[i].geom2))  # fmt: skip
                found.append(f"{'/'.join(names)} {1e3 * d.contact[i].dist:+.3f} mm "
                             f"{force[0]:.1f} N")  # fmt: skip
            contacts.append((step * config.timestep, float(lane.state.axial[0]), found))

    changes = search_changes(args.search)  # the evaluation's skill, with some constants changed
    config = config.replace(search=config.search.replace(**changes))
    if changes:
        print("search constants:", "; ".join(f"{k}={v}" for k, v in changes.items()))
    params = as_controller_params(params, 1)
    engine.run_on_cpu(specs, params, config, threads=1, slots_per_thread=1, observer=observe)
    trace = {k: np.asarray(v) for k, v in trace.items()}
    trace["dt"] = config.timestep
    trace["hole_xy"] = np.asarray(specs.board_pos[0])
    return trace, contacts


def report(trace: dict) -> None:
    dt = float(trace["dt"])
    last = int(round(1.0 / dt))
    axial, sensed = trace["axial"][-last:], trace["sensed"][-last:]
    lost = int(np.sum(np.abs(axial) < 0.25 * np.median(np.abs(axial))))
    spectrum = np.abs(np.fft.rfft(axial - axial.mean())) * 2 / axial.size
    freqs = np.fft.rfftfreq(axial.size, dt)
    lines = np.argsort(spectrum[1:])[::-1][:4] + 1
    width = int(round(0.05 / dt))
    z = trace["tcp"][-last:, 2]
    vibration = (z - np.convolve(z, np.ones(width) / width, mode="same"))[width:-width]
    off_axis = np.linalg.norm(trace["tip"][-last:, :2] - trace["hole_xy"], axis=1) * 1e3
    print(f"last second: true axial force mean {axial.mean():.1f} N, chatter (mean |dF|) "
          f"{np.abs(np.diff(axial)).mean():.2f} N; periods under a quarter of its median: "
          f"{lost} of {axial.size}")  # fmt: skip
    print("  spectrum lines: " + ", ".join(f"{freqs[i]:.0f} Hz {spectrum[i]:.2f} N" for i in lines))
    print(f"  the compliance's axial force: mean |dF| {np.abs(np.diff(sensed)).mean():.3f} N, "
          f"std {sensed.std():.3f} N")  # fmt: skip
    print(f"  tcp vertical vibration (rms about a 50 ms mean): "
          f"{1e6 * np.sqrt(np.mean(vibration**2)):.1f} um; tip from the hole axis "
          f"{off_axis.min():.1f}-{off_axis.max():.1f} mm")  # fmt: skip


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--eval", required=True, help="evaluation directory (eval.py --out)")
    p.add_argument("--range", type=int, required=True)
    p.add_argument("--trial", default="failure", help="index, failure or success")
    p.add_argument("--contacts-at", type=float, help="s: list the contacts from here on")
    p.add_argument("--search", default="", help="SkillConfig constants changed, 'NAME=V;...'")
    p.add_argument("--npz", help="write the per-period trace here")
    args = p.parse_args(argv)
    trace, contacts = replay(args)
    report(trace)
    for t, axial, found in contacts:
        print(f"  {t:.3f} s  axial {axial:6.1f} N  " + ("; ".join(found) or "no contact"))
    if args.npz:
        np.savez(args.npz, **trace)


if __name__ == "__main__":
    main()
