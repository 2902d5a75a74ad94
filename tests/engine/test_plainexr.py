"""Uncompressed EXRs read with NumPy alone (virtual_reflections/plainexr.py) give what
OpenImageIO reads: single- and multi-part, half, float and uint channels, a data window
inside the display window; compressed and damaged files are one-line errors."""

import numpy as np
import pytest

from virtual_reflections import atomic_files, imagefiles, plainexr

oiio = pytest.importorskip("OpenImageIO")


def write(path, parts, compression="none"):
    """parts: [(name, {channel: (H, W) array}, pixel type, data window or None)]."""
    out = oiio.ImageOutput.create(str(path))
    specs = []
    for name, channels, fmt, window in parts:
        h, w = next(iter(channels.values())).shape
        spec = oiio.ImageSpec(w, h, len(channels), fmt)
        spec.channelnames = tuple(channels)
        spec.attribute("compression", compression)
        spec.attribute("name", name)
        if window is not None:  # (x, y, full width, full height)
            spec.x, spec.y = window[0], window[1]
            spec.full_x, spec.full_y, spec.full_width, spec.full_height = 0, 0, *window[2:]
        specs.append(spec)
    assert out.open(str(path), tuple(specs)), out.geterror()
    for i, (_, channels, _, _) in enumerate(parts):
        if i:
            assert out.open(str(path), specs[i], "AppendSubimage"), out.geterror()
        pixels = np.stack(list(channels.values()), axis=-1)
        assert out.write_image(np.ascontiguousarray(pixels)), out.geterror()
    out.close()


def planes(rng, names, shape=(5, 7), scale=10.0):
    return {n: (rng.random(shape) * scale).astype(np.float32) for n in names}


def test_multipart_float_and_half_read_as_openimageio_reads(tmp_path):
    rng = np.random.default_rng(3)
    path = tmp_path / "passes.exr"
    write(path, [
        ("L.Combined", planes(rng, ["L.Combined.R", "L.Combined.G", "L.Combined.B"]), "float",
         None),
        ("L.Object Index", {"L.Object Index.X": np.rint(planes(rng, ["x"])["x"])}, "half",
         None),
    ])  # fmt: skip
    ours, theirs = plainexr.read_channels(str(path)), imagefiles.read_channels(str(path))
    assert sorted(ours) == sorted(theirs)
    for name in theirs:
        assert np.array_equal(ours[name], theirs[name]), name


def test_single_part_with_a_data_window_inside_the_display_window(tmp_path):
    rng = np.random.default_rng(4)
    path = tmp_path / "window.exr"
    data = planes(rng, ["A", "B", "G", "R"], shape=(3, 4))
    write(path, [("", data, "half", (2, 1, 8, 6))])
    ours = plainexr.read_channels(str(path))
    assert ours["R"].shape == (6, 8)
    half = data["R"].astype(np.float16).astype(np.float32)
    assert np.array_equal(ours["R"][1:4, 2:6], half)
    assert not ours["R"][0].any() and not ours["R"][:, :2].any()  # no data: zero


def test_compressed_missing_and_damaged_files_are_one_line_errors(tmp_path):
    path = tmp_path / "zip.exr"
    write(path, [("", planes(np.random.default_rng(5), ["R", "G", "B"]), "float", None)], "zip")
    with pytest.raises(atomic_files.ImageError, match="compressed EXR"):
        plainexr.read_channels(str(path))
    with pytest.raises(atomic_files.ImageError, match="image not found"):
        plainexr.read_channels(str(tmp_path / "missing.exr"))
    cut = tmp_path / "cut.exr"
    write(cut, [("", planes(np.random.default_rng(6), ["R"]), "float", None)])
    cut.write_bytes(cut.read_bytes()[:60])
    with pytest.raises(atomic_files.ImageError, match="cannot read") as err:
        plainexr.read_channels(str(cut))
    assert "\n" not in str(err.value)
