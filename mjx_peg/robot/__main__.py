import sys

from mjx_peg.robot.cli import main

sys.exit(main())
