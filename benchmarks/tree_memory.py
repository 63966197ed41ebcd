"""Peak memory of a command's whole process tree: the largest sum of PSS over the command and
every descendant alive at one time, sampled every 20 ms (Linux ``/proc/PID/smaps_rollup``).

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/tree_memory.py -- lopcook cook SOURCE -o OUT --lods 1/2,1/4

Why: ``ru_maxrss`` (``/usr/bin/time -f %M``, ``lopcook bench``) is the largest resident set of
any *one* process of the tree, so a cook that runs work in forked children beside its own can use
more memory than it reports. PSS (proportional set size) charges a page shared by k processes
(copy on write after a fork) 1/k to each, so the sum is what the tree occupies. Sampling can miss
a peak shorter than 20 ms. Prints ``tree PSS peak``, the largest single-process ``ru_maxrss`` and
the wall time.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time


def _children() -> dict[int, list[int]]:
    kids: dict[int, list[int]] = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        kids.setdefault(ppid, []).append(int(name))
    return kids


def _pss_kb(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def tree_pss_kb(root: int) -> int:
    kids, total, todo = _children(), 0, [root]
    while todo:
        pid = todo.pop()
        total += _pss_kb(pid)
        todo += kids.get(pid, [])
    return total


def main(argv: list[str]) -> int:
    cmd = argv[argv.index("--") + 1:] if "--" in argv else argv
    if not cmd:
        sys.exit(__doc__)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
    peak = 0
    while proc.poll() is None:
        peak = max(peak, tree_pss_kb(proc.pid))
        time.sleep(0.02)
    wall = time.perf_counter() - t0
    maxrss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    print(f"tree PSS peak {peak / 1024:.0f} MiB ({peak * 1024 / 1e6:.0f} MB); largest one-process "
          f"ru_maxrss {maxrss / 1024:.0f} MiB; wall {wall:.2f} s; exit {proc.returncode}")
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
