"""The end-to-end tests' diagnosis of a Blender without its OpenGL libraries (gl_libraries.py):
libEGL as well as libGL, named in the reason; anything else is not a missing library."""

import subprocess

import pytest
from gl_libraries import missing_gl, skip_without_gl

EGL = (
    "00:00.067  system.path      | WARNING Could not get a list of mounted file-systems\n"
    "Couldn't open libEGL.so.1: libEGL.so.1: cannot open shared object file: No such file or "
    "directoryAborted\n"
)
GL = "error while loading shared libraries: libGL.so.1: cannot open shared object file: No such"


def test_missing_libegl_is_named():
    reason = missing_gl(EGL)
    assert reason is not None and "libEGL.so.1" in reason and "libegl1" in reason
    assert "composites" in reason


def test_missing_libgl_is_named():
    reason = missing_gl(GL)
    assert reason is not None and "libGL.so.1" in reason and "window" in reason


def test_other_output_is_not_a_missing_library():
    assert missing_gl("") is None
    assert missing_gl("Saved: '/tmp/f12.png'\nBlender quit\n") is None
    assert missing_gl("Traceback (most recent call last):\nValueError: no plate\n") is None
    assert missing_gl("Info: loaded libEGL.so.1 through Mesa\n") is None


def test_an_aborted_background_render_skips_with_the_reason():
    aborted = subprocess.CompletedProcess(["blender"], 134, "", EGL)
    with pytest.raises(pytest.skip.Exception, match="cannot load libEGL.so.1"):
        skip_without_gl(aborted)
    skip_without_gl(subprocess.CompletedProcess(["blender"], 0, EGL, ""))  # it rendered: no skip
    skip_without_gl(subprocess.CompletedProcess(["blender"], 1, "", "Error: no plate"))
