"""Throughput harness: the same as ``falcon-rl bench`` (see benchmarks/README.md).

    python benchmarks/throughput.py --backend torch,warp --envs 1,64,1024,4096 --steps 100 \
        --baseline jsbsim --out benchmarks/results
"""

from __future__ import annotations

import sys

from falcon_rl.cli import main

if __name__ == "__main__":
    raise SystemExit(main(["bench", *sys.argv[1:]]))
