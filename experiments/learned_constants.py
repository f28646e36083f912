"""Which constants a policy moved from its start, and how far, per observation: a figure.

    python experiments/learned_constants.py --policy runs/paper/seed-0 [--policy ...]
        [--trials 400] [--out docs/design/learned_constants.png]

For trials drawn from each policy's training task (circle and square, its error ranges), the
policy's numbers per observation against its hand-tuned start (`TrainConfig.prior_vector`):
k_t, k_theta, the compliance's diagonal and the contact search's 9 constants, each as its ratio
to the start (log scale), one box per policy and shape. Prints the median ratio of each.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from mjx_peg.learn.config import TrainConfig
from mjx_peg.policy.export import load_policy
from mjx_peg.skill.params import LEARNED_NAMES, N_LEARNED
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.task import sample_trials

SHOWN = [0, 1] + [2 + 7 * i for i in range(6)] + list(range(38, N_LEARNED))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", action="append", required=True)
    p.add_argument("--trials", type=int, default=400)
    p.add_argument("--seed", type=int, default=11)
    p.add_argument("--out", default="learned_constants.png")
    args = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(12, 5), dpi=120)
    width = 0.8 / (2 * len(args.policy))
    for k, path in enumerate(args.policy):
        name = "/".join(pathlib.PurePath(path).parts[-2:])  # e.g. quick/seed-0
        policy = load_policy(path)
        config = TrainConfig.from_json(policy.manifest["config"])
        specs = sample_trials(config.task(), args.seed, args.trials)
        vectors = policy.controller_vectors(specs)
        prior = config.prior_vector()
        if vectors.shape[1] != N_LEARNED:
            raise SystemExit(f"{path} outputs {vectors.shape[1]} numbers, not {N_LEARNED}")
        for j, shape_id in enumerate(sorted(set(specs.shape_id.tolist()))):
            rows = vectors[specs.shape_id == shape_id][:, SHOWN]
            ratio = np.abs(rows) / np.maximum(np.abs(prior[SHOWN]), 1e-12)
            at = np.arange(len(SHOWN)) + (2 * k + j - len(args.policy)) * width + width / 2
            box = ax.boxplot(ratio, positions=at, widths=width * 0.9, showfliers=False,
                             patch_artist=True)  # fmt: skip
            for patch in box["boxes"]:
                patch.set_facecolor(f"C{2 * k + j}")
                patch.set_alpha(0.6)
            ax.plot([], [], color=f"C{2 * k + j}", lw=6, alpha=0.6,
                    label=f"{name}, {SHAPES[shape_id]}")  # fmt: skip
            medians = np.median(ratio, axis=0)
            moved = (f"{LEARNED_NAMES[i]} x{m:.2f}" for i, m in zip(SHOWN, medians, strict=True))
            print(f"{path} {SHAPES[shape_id]}: " + ", ".join(moved))
    ax.axhline(1.0, color="0.4", lw=1, ls=":")
    ax.set_yscale("log")
    ax.set_xticks(range(len(SHOWN)))
    ax.set_xticklabels([LEARNED_NAMES[i] for i in SHOWN], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("learned / hand-tuned start")
    ax.set_title("What learning moved, per observation (held-out contexts)")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
