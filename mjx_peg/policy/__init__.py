"""The policy: what it observes, its network's forward pass, and its portable export (NumPy only).

observation.py  the observation of a trial (the estimated hole, the part's geometry)
network.py      the MLP forward pass and its action -> the 38 controller numbers
export.py       policy.npz + manifest.json, written and read with allow_pickle=False
shipped.py      the policies shipped under policies/, by name
"""
