"""Plates in the file's working space (operators/scene/colour_space.py, images.read_linear).

Blender converts float buffers (EXR, 16-bit PNG) to the file's working space on load, but a byte
(8-bit) image's pixels stay its file's codes in the image's colour space. The reference here is
Blender's own conversion: the same codes written as a 16-bit PNG (k * 257 / 65535 = k / 255)
and tagged with the same colour space load as floats in the working space; the add-on's 8-bit
read must agree. Working spaces: Linear Rec.709 (4.5 and 5.x), Linear Rec.2020 and ACEScg (5.x,
per file). Tags: sRGB, Linear Rec.709, Display P3 (a non-sRGB 8-bit plate).
"""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
oiio = pytest.importorskip("OpenImageIO")

PER_FILE = hasattr(bpy.data, "colorspace")  # 5.x: the working space is per file
WORKING = ["Linear Rec.709"] + (["Linear Rec.2020", "ACEScg"] if PER_FILE else [])
TAGS = ["sRGB", "Linear Rec.709", "Display P3"]


@pytest.fixture
def plates(addon):
    return importlib.import_module(addon.__name__ + ".operators.scene.plate")


@pytest.fixture
def spaces(addon):
    return importlib.import_module(addon.__name__ + ".operators.scene.colour_space")


def set_working(name):
    if PER_FILE:
        bpy.ops.wm.set_working_color_space(working_space=name)
        assert bpy.data.colorspace.working_space == name


def codes():
    """(16, 16, 3) uint8: every 16th level in each channel, saturated and grey pixels."""
    k = np.arange(0, 256, 16, dtype=np.uint8)
    r, g = np.meshgrid(k, k[::-1])
    return np.stack([r, g, np.full_like(r, 40)], axis=-1)


def write_png(path, pixels):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    dtype = "uint8" if pixels.dtype == np.uint8 else "uint16"
    assert out.open(str(path), oiio.ImageSpec(w, h, c, dtype))
    out.write_image(pixels)
    out.close()
    return str(path)


def load(path, tag):
    image = bpy.data.images.load(path, check_existing=False)
    image.colorspace_settings.name = tag
    return image


@pytest.mark.parametrize("working", WORKING)
@pytest.mark.parametrize("tag", TAGS)
def test_8bit_plate_matches_blenders_own_float_conversion(plates, tmp_path, working, tag):
    set_working(working)
    c = codes()
    byte = load(write_png(tmp_path / "p8.png", c), tag)
    wide = load(write_png(tmp_path / "p16.png", c.astype(np.uint16) * 257), tag)
    assert not byte.is_float and wide.is_float
    ours, info = plates.image_pixels(byte)
    blender, _ = plates.image_pixels(wide)  # float: Blender converted it on load
    assert np.abs(ours - blender).max() < 1e-4, (info, np.abs(ours - blender).max())
    assert info.endswith("decoded to scene-linear") or working in info


@pytest.mark.parametrize("working", WORKING)
def test_srgb_plate_in_a_wide_working_space_is_not_more_saturated(plates, tmp_path, working):
    """The issue's case: an 8-bit sRGB red read as if Rec.709 in an ACEScg file is ~35 % more
    saturated; converted, its saturation (max - min) / max equals the 16-bit reference's."""
    set_working(working)
    red = np.zeros((4, 4, 3), np.uint8)
    red[...] = (200, 40, 30)
    ours, _ = plates.image_pixels(load(write_png(tmp_path / "r8.png", red), "sRGB"))
    wide = red.astype(np.uint16) * 257
    blender, _ = plates.image_pixels(load(write_png(tmp_path / "r16.png", wide), "sRGB"))

    def saturation(rgb):
        return float((rgb.max() - rgb.min()) / rgb.max())

    assert saturation(ours[0, 0]) == pytest.approx(saturation(blender[0, 0]), abs=1e-3)


def test_float_plate_is_used_as_blender_loaded_it(plates, tmp_path):
    set_working(WORKING[-1])
    values = np.full((2, 2, 3), (0.8, 0.2, 0.1), np.float32)
    path = str(tmp_path / "p.exr")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(2, 2, 3, "float"))
    out.write_image(values)
    out.close()
    image = load(path, "Linear Rec.709")
    ours, info = plates.image_pixels(image)
    stored = np.array(image.pixels[:], np.float32).reshape(2, 2, 4)[..., :3]
    assert np.array_equal(ours, stored) and WORKING[-1] in info


@pytest.mark.parametrize("working", WORKING)
def test_fallback_without_opencolorio_matches_it(spaces, working):
    """Blender's API route (used where Blender ships without PyOpenColorIO, e.g. distribution
    packages) agrees with OpenColorIO for the spaces it knows, both ways."""
    set_working(working)
    assert spaces.ocio() is not None, "the bpy wheel bundles PyOpenColorIO"
    rgb = np.random.default_rng(1).random((8, 8, 3), dtype=np.float32)
    for source in ("sRGB", "Display P3", "Linear Rec.709", "ACES2065-1", "Linear CIE-XYZ D65"):
        expected = spaces.convert(rgb, source, working)
        got = spaces.convert_blender(rgb, source, working)
        assert np.abs(got - expected).max() < 5e-4, (source, np.abs(got - expected).max())
    back = spaces.convert_blender(rgb, working, "Linear Rec.709")
    assert np.abs(back - spaces.convert(rgb, working, "Linear Rec.709")).max() < 1e-4
    with pytest.raises(ValueError, match="No Such Space"):
        spaces.convert(rgb, "No Such Space", working)
    with pytest.raises(ValueError, match="Filmic Log"):
        spaces.convert_blender(rgb, "Filmic Log", working)


@pytest.mark.parametrize("working", WORKING)
def test_preview_shows_the_plate_codes_back(spaces, plates, tmp_path, working):
    """The map back for display: working-space pixels -> sRGB codes, the plate's own codes."""
    set_working(working)
    c = codes()
    linear, _ = plates.image_pixels(load(write_png(tmp_path / "p8.png", c), "sRGB"))
    shown = np.rint(spaces.to_srgb(linear) * 255)
    assert np.abs(shown - c).max() <= 1


@pytest.mark.parametrize("working", WORKING)
def test_chrome_reflection_of_an_8bit_plate_renders_its_colour(addon, tmp_path, working):
    """End to end: a Replace (chrome) sphere reflecting a flat 8-bit sRGB plate renders, through
    the Standard view, the plate's own codes in every working space (an sRGB plate read as if
    in ACEScg would come out ~35 % more saturated)."""
    set_working(working)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location, camera.rotation_euler = (0, -6, 0), (np.pi / 2, 0, 0)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=32, ring_count=16)
    bpy.ops.object.shade_smooth()
    flat = np.zeros((48, 64, 3), np.uint8)
    flat[...] = (200, 90, 40)
    image = load(write_png(tmp_path / "flat.png", flat), "sRGB")
    settings = scene.virtual_reflections
    settings.plate_image, settings.combine, settings.resolution = image, "REPLACE", "256"
    settings.method = "PAPER"  # every direction of the map comes from the plate
    assert bpy.ops.vr.setup_plate(ground=False, lens=False) == {"FINISHED"}
    assert bpy.ops.vr.generate() == {"FINISHED"}
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples, scene.cycles.use_denoising = "CPU", 4, False
    scene.render.compositor_device = "CPU"
    scene.render.use_compositing = False  # the sphere alone
    output = scene.render.image_settings
    output.file_format, output.color_depth, output.color_mode = "PNG", "8", "RGBA"
    scene.render.filepath = str(tmp_path / "ball.png")
    bpy.ops.render.render(write_still=True)
    found = oiio.ImageInput.open(str(tmp_path / "ball.png"))
    rgba = found.read_image("uint8").astype(int)
    found.close()
    ball = rgba[rgba[..., 3] == 255][:, :3]
    assert len(ball) > 100
    error = np.abs(np.median(ball, axis=0) - (200, 90, 40))
    assert error.max() <= 2, np.median(ball, axis=0)
