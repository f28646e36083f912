"""Train a compliant insertion skill with Brax PPO. See `python train.py --help`."""

import sys

from mjx_peg.learn.cli import main

if __name__ == "__main__":
    sys.exit(main())
