"""mjx-peg: compliant peg-in-hole insertion learned with MuJoCo, MJX and Brax PPO."""
