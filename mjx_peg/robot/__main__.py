"""`python -m mjx_peg.robot`: a policy on the simulated arm (`robot/cli.py`)."""

import sys

from mjx_peg.robot.cli import main

sys.exit(main())
