"""Learning the 38 numbers with Brax's PPO, one trial per environment step.

config.py       TrainConfig and the presets (TrainConfig() is `quick`)
env.py          the Brax environment: one step = one trial on an engine
ppo.py          networks, training state, the PPO update
trainer.py      the training loop: resume, checkpoints, the export
run_dir.py      the run directory: config.json, metrics.csv, trials.csv
checkpoints.py  Orbax checkpoints (also the localizer's); restore_noise.py quiets a restore
curves.py       the learning curve
cli.py          python train.py
"""
