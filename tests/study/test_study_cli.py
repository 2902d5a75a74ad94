"""The study's command line: bad input is one line on stderr and exit code 2."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("repeat", ["0", "-3", "x"])
def test_bench_repeat_must_be_a_whole_number_of_runs(repeat):
    r = subprocess.run(
        [sys.executable, "-m", "study", "bench", "--repeat", repeat],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--repeat" in lines[0] and "nan" not in r.stdout
