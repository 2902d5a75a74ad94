"""Colour decoding and plate/map files: sRGB, 16-bit vs float, envmap header, atomic writes."""

import numpy as np
import OpenEXR
import OpenImageIO as oiio
import pytest

from virtual_reflections import environment_map
from virtual_reflections.atomic_files import ImageError
from virtual_reflections.colour import linear_to_srgb, srgb_to_linear
from virtual_reflections.imagefiles import read_plate, write_map


def test_srgb_half_decodes_to_0_214():
    assert float(srgb_to_linear(0.5)) == pytest.approx(0.21404, abs=1e-4)
    v = np.linspace(0, 1, 101, dtype=np.float32)
    assert np.allclose(linear_to_srgb(srgb_to_linear(v)), v, atol=1e-5)


def _write(path, pixels, fmt):
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], fmt)
    spec.attribute("oiio:UnassociatedAlpha", 1)
    buf = oiio.ImageBuf(spec)
    buf.set_pixels(oiio.ROI(), np.ascontiguousarray(pixels))
    assert buf.write(str(path)), buf.geterror()


def _picture():
    y, x = np.mgrid[0:120, 0:160]
    return np.stack([x / 160, y / 120, 0.5 + 0.4 * np.sin(x / 9.0)], -1).astype(np.float32)


def test_16bit_png_and_float_exr_give_the_same_map(tmp_path):
    linear = _picture()
    _write(tmp_path / "p.exr", linear, "float")
    _write(tmp_path / "p.png", np.round(linear_to_srgb(linear) * 65535).astype(np.uint16), "uint16")
    exr, png = read_plate(str(tmp_path / "p.exr")), read_plate(str(tmp_path / "p.png"))
    assert (exr.encoding, png.encoding) == ("linear", "sRGB")
    assert np.abs(exr.pixels - png.pixels).max() < 1e-3
    bbox = (60, 40, 100, 80)
    a, b = environment_map(exr.pixels, bbox, size=64), environment_map(png.pixels, bbox, size=64)
    assert np.abs(a - b).max() < 1e-3


def test_8bit_grey_with_alpha_becomes_rgb(tmp_path):
    grey = np.zeros((10, 12, 2), np.uint8)
    grey[..., 0], grey[..., 1] = 128, 7
    _write(tmp_path / "g.png", grey, "uint8")
    plate = read_plate(str(tmp_path / "g.png"))
    assert plate.pixels.shape == (10, 12, 3)
    assert np.allclose(plate.pixels, srgb_to_linear(128 / 255))


def test_nan_pixels_are_counted(tmp_path):
    linear = _picture()
    linear[5, 5] = np.nan
    linear[6, 6, 0] = np.inf
    _write(tmp_path / "n.exr", linear, "float")
    plate = read_plate(str(tmp_path / "n.exr"))
    assert plate.nonfinite == 4 and np.isfinite(plate.pixels).all()


@pytest.mark.parametrize("layout, name", [("latlong", "ENVMAP_LATLONG"), ("cube", "ENVMAP_CUBE")])
def test_exr_maps_carry_the_standard_envmap_attribute(tmp_path, layout, name):
    env = environment_map(_picture(), (60, 40, 100, 80), layout=layout, size=32)
    path = tmp_path / "m.exr"
    write_map(str(path), env, layout=layout)
    f = OpenEXR.File(str(path))
    assert f.header()["envmap"] == getattr(OpenEXR, name)
    assert f.channels()["RGB"].pixels.dtype == np.float16
    assert np.abs(f.channels()["RGB"].pixels.astype(np.float32) - env).max() < 2e-3


def test_ldr_maps_are_srgb_encoded(tmp_path):
    env = np.full((8, 16, 3), 0.214, np.float32)
    write_map(str(tmp_path / "m.png"), env)
    back = oiio.ImageBuf(str(tmp_path / "m.png")).get_pixels(oiio.UINT8)
    assert np.all(np.abs(back.astype(int) - 128) <= 1)


def test_bad_files(tmp_path):
    (tmp_path / "corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 20)
    (tmp_path / "empty.exr").write_bytes(b"")
    for name in ("missing.png", "corrupt.png", "empty.exr"):
        with pytest.raises(ImageError) as err:
            read_plate(str(tmp_path / name))
        assert "\n" not in str(err.value)
    with pytest.raises(ImageError, match="extension"):
        write_map(str(tmp_path / "m.bmpx"), np.zeros((2, 4, 3), np.float32))
    with pytest.raises(ImageError, match="does not exist"):
        write_map(str(tmp_path / "no" / "m.exr"), np.zeros((2, 4, 3), np.float32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corrupt.png", "empty.exr"]
