"""The learned skill on an arm, in NumPy alone (no JAX, no Brax: the robot's computer runs this).

    arm.py      ArmState (what one control period measures) and the Arm interface
    runtime.py  SkillRuntime (hole estimate + 38 numbers -> torques, safety checks), run_skill
    sim_arm.py  SimArm: a simulated UR5e (C MuJoCo, one trial) behind the Arm interface, with
                the real arm's command period (torques held between commands)
    cli.py      python -m mjx_peg.robot: run a policy on the simulated arm at a chosen command rate

The controller math is the one the trainer and both engines use
(`mjx_peg.skill.control_step`); only the loop around it lives here.
"""
