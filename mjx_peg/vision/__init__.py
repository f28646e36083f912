"""Vision to action (paper section 6.6): the hole's pose from a bird's-eye camera image.

    camera.py     CameraCalibration (intrinsics + pose in the base frame, JSON), projection,
                  rectification onto the board-top plane (NumPy)
    randomize.py  domain randomization of the bird's-eye scene (materials, lights, camera,
                  distractors, sensor)
    dataset.py    seeded, resumable PNG + JSON splits with exact labels
    views.py      the localizer's two top-down views (workspace, 140 mm around the hole)
    forward.py    the two CNNs in NumPy (the portable export's forward pass)
    nets.py       the same CNNs in Flax; training.py trains them (Optax, Orbax checkpoints)
    localizer.py  Localizer: image + calibration -> robot.runtime.HoleEstimate (NumPy only)
    metrics.py    error percentiles per shape on a split
    act.py        trials whose hole estimate comes from the localizer
    figures.py    README pictures
    cli.py        python -m mjx_peg.vision render|train|evaluate|localize|act|figures

Inference (camera, views, forward, localizer) needs NumPy alone: the robot runtime can import
`mjx_peg.vision.localizer` without JAX. Nothing here is imported by the rest of the package.
"""
