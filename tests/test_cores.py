"""cores.py: the cores a process may use are its CPU affinity, not the machine's count."""

from __future__ import annotations

import os
import subprocess
import sys


def test_cores_is_the_processs_affinity():
    from mjx_peg.cores import cores

    assert cores() == len(os.sched_getaffinity(0))
    code = "import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})\n"
    code += "from mjx_peg.cores import cores; print(cores(), os.cpu_count())"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    ours, machine = map(int, done.stdout.split())
    assert ours == 1 and machine == os.cpu_count()
