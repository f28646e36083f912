"""The policy: what it observes, its network's forward pass, and its portable export (NumPy only).

observation.py  what the policy sees of a trial: the estimated hole pose and the part, in a
                layout of names (the shipped policies') or of geometry (any part)
network.py      the deterministic forward pass: observation -> 38 controller numbers
export.py       policy.npz + manifest.json, written and read with allow_pickle=False
shipped.py      the policies shipped under policies/, by name
"""
