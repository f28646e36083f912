"""The skill's math (paper sections 3-4), written once over the array-API namespace of its inputs
and batched over leading dimensions; no module here imports numpy or jax at the top.

    dmp.py           the compliant DMP (Eqs. 1-11)
    osc.py           the task state and the operational-space torque (Eq. 14)
    sensor.py        the F/T sensor as the controller sees it
    params.py        the 38 learned numbers and the maps from a policy's action onto them
    search.py        the contact search (an extension), SkillConfig and the named skills
    control_step.py  one control period: measured arm state -> joint torques
    baseline.py      the hand-tuned 38 numbers
"""
