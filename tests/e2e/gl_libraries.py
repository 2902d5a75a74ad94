"""Why a real Blender could not draw or composite: the OpenGL library it could not load.

Blender draws its window through libGL and, in Blender 5.x, composites even a background
render on the GPU module, which loads libEGL: a build without them (the Debian package
installed without its recommended Mesa libraries, as in the test chroot) aborts there, with no
extension loaded. The end-to-end tests skip with this reason instead of failing on it."""

import re

import pytest

# "Couldn't open libEGL.so.1: libEGL.so.1: cannot open shared object file: ..." (5.2, Debian)
# and "libGL.so.1: cannot open shared object file" (a window without Mesa).
_MISSING = re.compile(r"\b(libE?GL\.so(?:\.\d+)*)\b[^\n]*?(?:cannot open|not found|Couldn't open)")
_OPENING = re.compile(r"Couldn't open (libE?GL\.so(?:\.\d+)*)")
PACKAGES = "libegl1 libgl1 libgl1-mesa-dri"  # Debian's names for Mesa's EGL, GL and drivers


def missing_gl(output: str) -> str | None:
    """The reason to skip when Blender's ``output`` (stdout + stderr) says it could not load
    libGL or libEGL, else None.

    Parameters
    ----------
    output : str
        What the Blender process printed.

    Returns
    -------
    str or None
        One line naming the library and what to install, or None.
    """
    found = _OPENING.search(output) or _MISSING.search(output)
    if found is None:
        return None
    library = found.group(1)
    use = "composites (even in the background)" if "EGL" in library else "draws its window"
    return (
        f"the Blender binary cannot load {library}: it {use} through it "
        f"(install {PACKAGES} where Blender runs)"
    )


def skip_without_gl(result, failed_only=True):
    """Skip the running test with `missing_gl`'s reason when the Blender run ``result`` (a
    CompletedProcess) could not load libGL or libEGL; with ``failed_only`` (a background run)
    only when it also failed."""
    if failed_only and result.returncode == 0:
        return
    reason = missing_gl((result.stdout or "") + (result.stderr or ""))
    if reason is not None:
        pytest.skip(reason)
