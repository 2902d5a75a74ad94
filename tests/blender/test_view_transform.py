"""Set Up From Plate makes the composite's background the plate (operators/compositor.py):

- the view transform: a tone-mapping view (AgX, the default) repaints the plate in the saved
  composite; Set Up sets Standard on an sRGB display, records what it changed, Undo puts it back;
- the render size: the compositor scales the plate to the render size (Resolution % and pixel
  aspect), so F12 at 25/50/200 % shows the whole plate, not its centre at 1:1.

Renders are Cycles CPU, 1 sample, an empty scene (so the composite is the plate alone).
Colour: 8-bit PNG files are sRGB-encoded codes; EXR files scene-linear Rec.709.
"""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
oiio = pytest.importorskip("OpenImageIO")


@pytest.fixture
def comp(addon):
    return importlib.import_module(addon.__name__ + ".operators.compositor")


def write_image(path, pixels, dtype):
    height, width, channels = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(width, height, channels, dtype)), oiio.geterror()
    assert out.write_image(pixels), out.geterror()
    out.close()
    return path


def read_image(path, dtype="float"):
    image = oiio.ImageInput.open(str(path))
    assert image is not None, oiio.geterror()
    pixels = image.read_image(dtype)
    image.close()
    return pixels


def photo(width=48, height=32):
    """(H, W, 3) uint8 saturated colours and a ramp: what a tone-mapping view changes most."""
    rng = np.random.default_rng(7)
    pixels = rng.integers(0, 256, size=(height, width, 3)).astype(np.uint8)
    pixels[: height // 2, : width // 2] = [200, 40, 30]  # a saturated red block
    pixels[-1] = np.linspace(0, 255, width).astype(np.uint8)[:, None]
    return pixels


def empty_scene(tmp_path, plate):
    """The current (empty factory) scene with a camera and nothing to render; Cycles CPU."""
    scene = bpy.context.scene
    data = bpy.data.cameras.new("Camera")
    camera = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.compositor_device = "CPU"
    return scene, bpy.data.images.load(str(plate))


def render_png(scene, path):
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "PNG", "8", "RGB"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_image(path, "uint8").astype(np.int16)


def test_default_file_is_tone_mapped_and_setup_sets_standard(comp, tmp_path):
    scene = bpy.context.scene
    assert scene.view_settings.view_transform == "AgX"  # Blender's default since 4.0
    plate = write_image(tmp_path / "plate.png", photo(), "uint8")
    scene, image = empty_scene(tmp_path, plate)
    record = comp.setup_from_plate(scene, image)
    assert scene.view_settings.view_transform == "Standard"
    assert record["view"] == {"view_settings.view_transform": "AgX"}
    assert comp.describe_view(record["view"]) == "view transform AgX -> Standard"
    comp.undo_setup_from_plate(scene)
    assert scene.view_settings.view_transform == "AgX"


def test_every_view_setting_is_recorded_and_undone(comp, tmp_path):
    plate = write_image(tmp_path / "plate.png", photo(8, 6), "uint8")
    scene, image = empty_scene(tmp_path, plate)
    view = scene.view_settings
    view.view_transform, view.look = "Filmic", "High Contrast"
    view.exposure, view.gamma, view.use_curve_mapping = 1.5, 0.8, True
    if hasattr(view, "use_white_balance"):
        view.use_white_balance = True
    output = scene.render.image_settings
    output.color_management = "OVERRIDE"  # a saved file with a view of its own
    before = {k: getattr(view, k) for k in ("view_transform", "look", "exposure", "gamma")}
    record = comp.setup_from_plate(scene, image)
    assert output.color_management == "FOLLOW_SCENE"
    assert (view.view_transform, view.look, view.exposure, view.gamma) == (
        "Standard",
        "None",
        0.0,
        1.0,
    )
    assert not view.use_curve_mapping
    assert not getattr(view, "use_white_balance", False)
    said = comp.describe_view(record["view"])
    assert "view transform Filmic -> Standard" in said and "curves off" in said
    comp.setup_from_plate(scene, image)  # again: still undoes to the first state
    comp.undo_setup_from_plate(scene)
    assert {k: getattr(view, k) for k in before} == before
    assert output.color_management == "OVERRIDE"
    assert view.use_curve_mapping
    assert getattr(view, "use_white_balance", True)


def test_setup_on_a_standard_file_changes_nothing_of_the_view(comp, tmp_path):
    plate = write_image(tmp_path / "plate.png", photo(8, 6), "uint8")
    scene, image = empty_scene(tmp_path, plate)
    scene.view_settings.view_transform = "Standard"
    record = comp.setup_from_plate(scene, image)
    assert record["view"] == {} and comp.describe_view(record["view"]) == ""


def test_f12_background_equals_an_8bit_plate(comp, tmp_path):
    """Default file (AgX): the composite differs from the photo; after Set Up it is the photo
    within 1 level (the issue's figures: AgX ~23 levels on average)."""
    codes = photo()
    plate = write_image(tmp_path / "plate.png", codes, "uint8")
    scene, image = empty_scene(tmp_path, plate)
    output = scene.render.image_settings
    output.color_management = "OVERRIDE"  # and the output's own view tone-maps too
    output.view_settings.view_transform = "Filmic"
    comp.setup_from_plate(scene, image)
    after = render_png(scene, tmp_path / "after.png")
    scene.view_settings.view_transform = "AgX"  # what the file had: the plate repainted
    agx = render_png(scene, tmp_path / "agx.png")
    error = np.abs(after - codes)
    print(f"Standard: max {error.max()} mean {error.mean():.3f} levels; "
          f"AgX: mean {np.abs(agx - codes).mean():.1f} levels")  # fmt: skip
    assert error.max() <= 1
    assert np.abs(agx - codes).mean() > 5


def ramp_plate(width, height):
    """(H, W, 3) float32 linear in x (red) and y (green): any resampling of it at a continuous
    position (u, v) in [0, 1]^2 reads (u, v, 0.25) away from the edges."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    return np.stack([(x + 0.5) / width, (y + 0.5) / height, np.full_like(x, 0.25)], axis=-1)


@pytest.mark.parametrize(
    "percent, aspect", [(25, 1.0), (50, 1.0), (100, 1.0), (200, 1.0), (50, 2.0)]
)
def test_plate_fills_the_render_at_any_resolution_percentage(comp, tmp_path, percent, aspect):
    width, height = 64, 32
    plate = write_image(tmp_path / "plate.exr", ramp_plate(width, height), "float")
    scene, image = empty_scene(tmp_path, plate)
    comp.setup_from_plate(scene, image)
    render = scene.render
    render.resolution_percentage = percent
    render.pixel_aspect_x = aspect  # anamorphic: render pixels still map to plate pixels
    settings = render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "OPEN_EXR", "32", "RGB"
    render.filepath = str(tmp_path / "out.exr")
    bpy.ops.render.render(write_still=True)
    out = read_image(tmp_path / "out.exr")
    w, h = width * percent // 100, height * percent // 100
    assert out.shape[:2] == (h, w)
    expected = ramp_plate(w, h)  # the plate stretched to the render size
    inner = (slice(1, -1), slice(1, -1))  # resampling at the edges clamps
    error = np.abs(out[inner][..., :3] - expected[inner])
    assert error.max() < 0.02, f"max error {error.max():.4f}"


def test_panel_warns_when_the_view_is_changed_back(comp, tmp_path):
    plate = write_image(tmp_path / "plate.png", photo(8, 6), "uint8")
    scene, image = empty_scene(tmp_path, plate)
    assert comp.view_warning(scene) is None  # not set up: nothing to say
    comp.setup_from_plate(scene, image)
    assert comp.view_warning(scene) is None
    scene.view_settings.view_transform = "AgX"
    assert comp.view_warning(scene) == (
        "View transform AgX repaints the plate in the composite (Standard keeps it)"
    )
    comp.undo_setup_from_plate(scene)
    assert comp.view_warning(scene) is None


def test_operator_reports_what_it_changed(addon, tmp_path, capfd):
    plate = write_image(tmp_path / "plate.png", photo(8, 6), "uint8")
    scene, image = empty_scene(tmp_path, plate)
    scene.virtual_reflections.plate_image = image
    capfd.readouterr()
    assert bpy.ops.vr.setup_plate(ground=False) == {"FINISHED"}
    said = capfd.readouterr()
    assert "view transform AgX -> Standard so the composite keeps the plate's colours" in (
        said.out + said.err
    )
    assert bpy.ops.vr.undo_setup_plate() == {"FINISHED"}
    assert scene.view_settings.view_transform == "AgX"
