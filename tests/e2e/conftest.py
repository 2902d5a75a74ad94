"""A real Blender binary for end-to-end tests: $VR_BLENDER (a command), `blender` on PATH, or
the project's Debian chroot tool ($VR_BLENDER_CHROOT, or shared/tools/blender-chroot one or
two folders above the checkout) once set up. Tests skip
with the reason when none is found."""

import os
import shlex
import shutil
import signal
import subprocess
from pathlib import Path

import pytest
from gl_libraries import skip_without_gl

ROOT = Path(__file__).resolve().parents[2]
# The chroot tool, found relative to the checkout (or named by $VR_BLENDER_CHROOT).
CHROOT_TOOLS = [
    *([Path(os.environ["VR_BLENDER_CHROOT"])] if os.environ.get("VR_BLENDER_CHROOT") else []),
    ROOT.parent / "shared/tools/blender-chroot",
    ROOT.parent.parent / "shared/tools/blender-chroot",
]


def find_blender():
    """(command prefix list, description) or (None, reason)."""
    if os.environ.get("VR_BLENDER"):
        return shlex.split(os.environ["VR_BLENDER"]), "$VR_BLENDER"
    if shutil.which("blender"):
        return [shutil.which("blender")], "blender on PATH"
    for tool in CHROOT_TOOLS:
        if tool.is_file() and os.access(tool, os.X_OK):
            root = subprocess.run(
                [str(tool), "path"], capture_output=True, text=True
            ).stdout.strip()
            if root and (Path(root) / ".vr-ready").exists():
                return [str(tool), "blender"], f"chroot {root}"
            return None, f"the Blender chroot is not set up (run: {tool} setup)"
    return None, "no Blender binary: set VR_BLENDER, put blender on PATH, or set up the chroot"


@pytest.fixture(scope="session")
def blender():
    command, why = find_blender()
    if command is None:
        pytest.skip(why)

    def run(*args, env=None, cwd=None, timeout=600, wrap=()):
        # In a session of its own, so that a timeout ends Blender and Xvfb too, not only
        # the wrapper (xvfb-run, the chroot tool) that started them.
        with subprocess.Popen(
            [*wrap, *command, *map(str, args)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, **(env or {})},
            cwd=cwd or ROOT,
            start_new_session=True,
        ) as process:
            try:
                stdout, stderr = process.communicate(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.communicate()
                raise
        result = subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)
        skip_without_gl(result)  # a Blender that aborts without libGL / libEGL: say so
        return result

    return run


@pytest.fixture(scope="session")
def blender_gui(blender):
    """Run a script in Blender with its window, on a virtual X display (xvfb-run)."""
    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run is not installed (apt-get install xvfb)")

    def run(script, *args, timeout=300):
        r = blender(
            "--factory-startup",
            "--python",
            script,
            "--",
            *args,
            timeout=timeout,
            wrap=["xvfb-run", "-a", "-s", "-screen 0 1280x800x24"],
        )
        skip_without_gl(r, failed_only=False)
        return r

    return run
