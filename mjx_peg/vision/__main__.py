"""`python -m mjx_peg.vision`: see mjx_peg/vision/cli.py."""

import sys

from mjx_peg.vision.cli import main

if __name__ == "__main__":
    sys.exit(main())
