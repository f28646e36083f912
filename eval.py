"""Evaluate a policy over the paper's grid of error ranges: `python eval.py --help`."""

from mjx_peg.evaluation.eval_cli import main

if __name__ == "__main__":
    raise SystemExit(main())
