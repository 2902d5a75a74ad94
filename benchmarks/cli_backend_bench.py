"""Benchmark: one engine command line call (`python -m virtual_reflections envmap`), the whole
process, with each gather back end — which is faster for a one-shot map?

Each call is a fresh process, as a TD's script or a compositor's node runs it: it pays for
importing the back end (Numba: llvmlite and the cached kernels, after
`python -m virtual_reflections.warmup`) once per map. Printed per width: the median wall time
of each back end over --runs calls, and their ratio. The engine's command line picks the
back end this measures as faster (NumPy); a sequence of maps in one process (the batch, Live
Update) is where the compiled kernels pay (docs/benchmarks.md).

    .venv/bin/python benchmarks/cli_backend_bench.py [--runs 5] [--widths 256 1024 4096]
"""

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
PLATE = ROOT / "sample_scenes/plates/courtyard.jpg"


def one_call(gather: str, width: int, out: str) -> float:
    command = [sys.executable, "-m", "virtual_reflections", "envmap", str(PLATE), "-o", out]
    command += ["--bbox", "500", "300", "780", "600", "--hfov", "60", "--width", str(width)]
    started = time.perf_counter()
    subprocess.run(command, cwd=ROOT, check=True, capture_output=True,
                   env={**os.environ, "VR_GATHER": gather})
    return time.perf_counter() - started


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--widths", type=int, nargs="+", default=[256, 1024, 4096])
    args = p.parse_args(argv)
    if args.runs < 1:
        print("cli_backend_bench: error: --runs must be at least 1", file=sys.stderr)
        return 2
    subprocess.run([sys.executable, "-m", "virtual_reflections.warmup"], cwd=ROOT, check=True)
    print(f"{'width':>6} {'numba s':>9} {'numpy s':>9} {'numba/numpy':>12}")
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "map.exr")
        for width in args.widths:
            times = {"numba": [], "numpy": []}
            for _ in range(args.runs):  # interleaved: the machine's load falls on both
                for gather in times:
                    times[gather].append(one_call(gather, width, out))
            numba, numpy = (statistics.median(times[g]) for g in ("numba", "numpy"))
            print(f"{width:6d} {numba:9.2f} {numpy:9.2f} {numba / numpy:12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
