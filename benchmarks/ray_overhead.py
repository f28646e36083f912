"""What a call of the CPU engine costs on Ray beyond its trials, against the local process pool.

    python benchmarks/ray_overhead.py [--trials 64] [--calls 5] [--write]

Runs `run_trials` on `--trials` trials that end at once (a 10 ms limit: 5 physics steps each),
so a call's time is its overhead: local lanes as threads (1 lane), the local process pool (one
worker per core) and a local Ray cluster (`ray="local"`, one actor per core, one piece per actor
at this size). Median of `--calls` calls after one warm-up call (which starts the workers).
`--write` replaces the "## Ray cluster: overhead per call" section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _report import ROOT, cpu_name, write_section  # benchmarks/ is on sys.path when run

from mjx_peg.engines import ray_pool, run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

HEADING = "## Ray cluster: overhead per call"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=64)
    ap.add_argument("--calls", type=int, default=5)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    specs = sample_trials(TaskConfig(), 0, args.trials)
    config = TrialConfig(time_limit_s=0.01)
    cores = os.cpu_count()
    rows = []
    start = time.perf_counter()
    ray_pool.connect("local")
    startup = time.perf_counter() - start
    modes = (
        ("lanes as threads (1 lane)", dict(threads=1)),
        (f"process pool ({cores} workers)", dict(processes=cores)),
        (f"Ray, local cluster ({cores} actors, one piece each)", dict(ray="local")),
    )
    for label, options in modes:
        run_trials(specs, baseline_params(), "mujoco", config, **options)  # warm-up
        times = []
        for _ in range(args.calls):
            t0 = time.perf_counter()
            run_trials(specs, baseline_params(), "mujoco", config, **options)
            times.append(time.perf_counter() - t0)
        rows.append(f"| {label} | {1000 * np.median(times):.1f} |")
    lines = [
        HEADING,
        "",
        f"`run_trials` on {args.trials} trials that end at once (10 ms limit), median of "
        f"{args.calls} calls after a warm-up, on {cpu_name()} ({cores} cores, shared). Starting "
        f"the local Ray cluster and its actors took {startup:.1f} s. Command: "
        f"`python benchmarks/ray_overhead.py --trials {args.trials} --calls {args.calls} --write`.",
        "",
        "| how | ms per call |",
        "|---|---|",
        *rows,
        "",
    ]
    text = "\n".join(lines)
    print(text)
    ray_pool.shutdown()
    if args.write:
        write_section(ROOT / "BENCHMARKS.md", HEADING, text)


if __name__ == "__main__":
    main()
