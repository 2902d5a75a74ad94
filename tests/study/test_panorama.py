"""Panorama geometry: Blender's lat-long, its camera, the camera frame, plates, ground truth.

Pictures whose answer is known: a world whose -X half is red and +X half blue, and a smooth
world coloured by its own direction (so bilinear sampling is close to exact).
"""

import json
import math
import pathlib

import numpy as np
import pytest

from study import panorama as P

ROOT = pathlib.Path(__file__).resolve().parents[2]
PLATES = ROOT / "sample_scenes" / "plates"
RNG = np.random.default_rng(7)


def random_directions(n):
    d = RNG.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def equirect_from(colour_of_direction, width=512):
    """A Blender-convention lat-long `(W/2, W, 3)` whose pixel centres hold colour(direction)."""
    height = width // 2
    x, y = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    dirs = P.blender_equirect_direction(np.stack([x, y], -1), width, height)
    return colour_of_direction(dirs).astype(np.float32)


def smooth_world(width=512):
    return equirect_from(lambda d: 0.5 + 0.4 * d, width)


def left_right_world(width=256):
    """World -X red, +X blue (Blender world frame); green added above the horizon."""

    def colour(d):
        red = (d[..., 0] < 0).astype(float)
        green = 0.5 * (d[..., 2] > 0)
        return np.stack([red, green, 1.0 - red], -1)

    return equirect_from(colour, width)


# --- Blender's lat-long ------------------------------------------------------------------------


def test_equirect_round_trip():
    dirs = random_directions(1000)
    xy = P.blender_equirect_lookup(dirs, 1024, 512)
    assert np.all((xy[:, 0] >= 0) & (xy[:, 0] < 1024) & (xy[:, 1] >= 0) & (xy[:, 1] <= 512))
    np.testing.assert_allclose(P.blender_equirect_direction(xy, 1024, 512), dirs, atol=1e-12)
    # and pixel -> direction -> pixel
    pixels = RNG.uniform([0, 1], [1024, 511], size=(1000, 2))
    back = P.blender_equirect_lookup(P.blender_equirect_direction(pixels, 1024, 512), 1024, 512)
    np.testing.assert_allclose(back, pixels, atol=1e-9)


@pytest.mark.parametrize(
    ("direction", "expected"),
    [
        ((1, 0, 0), (512, 256)),  # world +X: the centre of the image
        ((0, 1, 0), (256, 256)),  # world +Y: a quarter from the left
        ((0, -1, 0), (768, 256)),  # world -Y: three quarters
        ((0, 0, 1), (None, 0)),  # the zenith: the top edge
        ((0, 0, -1), (None, 512)),  # the nadir: the bottom edge
        ((1, 0, 1), (512, 128)),  # 45 degrees up
    ],
)
def test_equirect_known_directions(direction, expected):
    """Cycles' direction_to_equirectangular: u = 0.5 - atan2(y, x) / 2pi, v = 1 - acos(z) / pi."""
    x, y = P.blender_equirect_lookup(np.array(direction, float), 1024, 512)
    if expected[0] is not None:
        assert x == pytest.approx(expected[0])
    assert y == pytest.approx(expected[1])


def test_sample_equirect_bilinear_and_wraps():
    image = np.zeros((4, 8, 3), np.float32)
    image[:, 0] = 1.0  # first column white, last column black
    # the seam (u = 0, world -X) lies between the last and the first column: half of each
    seam = P.blender_equirect_direction(np.array([0.0, 2.0]), 8, 4)
    np.testing.assert_allclose(P.sample_equirect(image, seam), 0.5, atol=1e-6)
    # a pixel centre returns the pixel
    centre = P.blender_equirect_direction(np.array([0.5, 1.5]), 8, 4)
    np.testing.assert_allclose(P.sample_equirect(image, centre), 1.0, atol=1e-6)
    # shapes: (..., 3) in, (..., 3) float32 out
    out = P.sample_equirect(image, random_directions(12).reshape(3, 4, 3))
    assert out.shape == (3, 4, 3) and out.dtype == np.float32


# --- the Blender camera ------------------------------------------------------------------------


def forward_up_right(rotation):
    """Blender camera looks down local -Z, +Y up, +X right."""
    return rotation @ (0, 0, -1), rotation @ (0, 1, 0), rotation @ (1, 0, 0)


def test_camera_rotation_heading_zero_looks_along_world_y():
    forward, up, right = forward_up_right(P.camera_rotation(0, 0))
    np.testing.assert_allclose(forward, (0, 1, 0), atol=1e-12)
    np.testing.assert_allclose(up, (0, 0, 1), atol=1e-12)
    np.testing.assert_allclose(right, (1, 0, 0), atol=1e-12)


def test_camera_rotation_heading_turns_left_and_pitch_looks_up():
    forward, up, _ = forward_up_right(P.camera_rotation(90, 0))
    np.testing.assert_allclose(forward, (-1, 0, 0), atol=1e-12)  # counter-clockwise from above
    forward, up, _ = forward_up_right(P.camera_rotation(0, 30))
    np.testing.assert_allclose(forward, (0, math.cos(math.radians(30)), 0.5), atol=1e-12)
    assert up[2] > 0
    _, up, right = forward_up_right(P.camera_rotation(0, 0, 20))
    assert up[0] < 0 and right[2] > 0  # rolled counter-clockwise seen from behind


@pytest.mark.parametrize(
    ("heading", "pitch", "roll"), [(0, 0, 0), (-120, -8, 0), (37, 25, 0), (-150, 10, 15)]
)
def test_camera_euler_matches_rotation(heading, pitch, roll):
    euler = P.camera_rotation_euler(heading, pitch, roll)
    np.testing.assert_allclose(
        P.euler_xyz_to_matrix(euler), P.camera_rotation(heading, pitch, roll), atol=1e-12
    )


def test_lens_from_horizontal_fov():
    assert P.lens_mm(60.0) == pytest.approx(18.0 / math.tan(math.radians(30)))
    assert P.focal_length_pixels(1280, 90.0) == pytest.approx(640.0)


# --- the camera frame --------------------------------------------------------------------------


def test_camera_frame_directions_follow_the_conventions():
    w, h, hfov = 40, 24, 70.0
    dirs = P.camera_frame_directions(w, h, hfov)
    assert dirs.shape == (h, w, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0)
    f = (w / 2) / math.tan(math.radians(hfov) / 2)
    px, py = 3, 17
    expected = np.array([-(px + 0.5 - w / 2) / f, -(py + 0.5 - h / 2) / f, 1.0])
    np.testing.assert_allclose(dirs[py, px], expected / np.linalg.norm(expected))
    assert np.all(dirs[:, 0, 0] > 0)  # column 0, the plate's left edge, is camera +X
    assert np.all(dirs[:, -1, 0] < 0)
    assert np.all(dirs[0, :, 1] > 0)  # row 0 is up
    # the outer pixel edges span the horizontal field of view
    left = P.camera_frame_directions(w, h, hfov, subpixel=(0.0, 0.0))[h // 2, 0]
    right = P.camera_frame_directions(w, h, hfov, subpixel=(1.0, 0.0))[h // 2, -1]
    assert math.degrees(math.acos(left @ right)) == pytest.approx(hfov)


def test_odd_plate_centre_looks_forward():
    dirs = P.camera_frame_directions(41, 23, 60.0)
    np.testing.assert_allclose(dirs[11, 20], (0, 0, 1), atol=1e-12)


def test_camera_frame_is_blender_camera_local_turned_about_y():
    rotation = P.camera_rotation(-120, -8, 5)
    forward, up, right = forward_up_right(rotation)
    axes = P.camera_to_blender_world(np.eye(3), rotation)
    np.testing.assert_allclose(axes[2], forward, atol=1e-12)  # camera +Z: forward
    np.testing.assert_allclose(axes[1], up, atol=1e-12)  # camera +Y: up
    np.testing.assert_allclose(axes[0], -right, atol=1e-12)  # camera +X: the plate's left
    dirs = random_directions(50)
    np.testing.assert_allclose(
        P.blender_world_to_camera(P.camera_to_blender_world(dirs, rotation), rotation), dirs
    )


# --- plates and ground truth -------------------------------------------------------------------


def test_plate_left_half_sees_the_worlds_left():
    """Heading 0 looks along world +Y, so the plate's left is world -X (red)."""
    plate = P.perspective_plate(left_right_world(), 64, 36, 60.0, 0.0, 0.0)
    assert plate.shape == (36, 64, 3) and plate.dtype == np.float32
    assert np.all(plate[:, :30, 0] > 0.99) and np.all(plate[:, :30, 2] < 0.01)
    assert np.all(plate[:, 34:, 2] > 0.99) and np.all(plate[:, 34:, 0] < 0.01)
    assert np.all(plate[:16, :, 1] > 0.49) and np.all(plate[20:, :, 1] < 0.01)  # sky is up


@pytest.mark.parametrize(("heading", "pitch", "roll"), [(0, 0, 0), (-90, 20, 0), (150, -8, 10)])
def test_plate_centre_is_the_hdri_along_the_camera_forward(heading, pitch, roll):
    world = smooth_world()
    forward = P.camera_rotation(heading, pitch, roll) @ (0, 0, -1)
    expected = P.sample_equirect(world, forward)
    plate = P.perspective_plate(world, 41, 23, 60.0, heading, pitch, roll, supersample=1)
    np.testing.assert_allclose(plate[11, 20], expected, atol=1e-6)
    plate = P.perspective_plate(world, 41, 23, 60.0, heading, pitch, roll, supersample=3)
    np.testing.assert_allclose(plate[11, 20], expected, atol=2e-3)
    np.testing.assert_allclose(plate[11, 20], 0.5 + 0.4 * forward, atol=2e-3)


def test_ground_truth_centre_is_the_plate_centre():
    """The map's centre (between columns W/2 - 1 and W/2, rows H/2 - 1 and H/2) is forward."""
    world = smooth_world()
    heading, pitch = -120.0, -8.0
    rotation = P.camera_rotation(heading, pitch)
    latlong = P.ground_truth_latlong(world, rotation, 256)
    assert latlong.shape == (128, 256, 3) and latlong.dtype == np.float32
    plate = P.perspective_plate(world, 41, 23, 60.0, heading, pitch)
    centre = latlong[63:65, 127:129].mean(axis=(0, 1))
    np.testing.assert_allclose(centre, plate[11, 20], atol=2e-3)


def test_ground_truth_is_upright_and_unmirrored():
    latlong = P.ground_truth_latlong(left_right_world(), P.camera_rotation(0, 0), 128)
    h, w = latlong.shape[:2]
    # camera +X (left of centre in the map) is the plate's left: world -X, red
    assert np.all(latlong[:, w // 2 - 20 : w // 2 - 2, 0] > 0.99)
    assert np.all(latlong[:, w // 2 + 2 : w // 2 + 20, 2] > 0.99)
    assert np.all(latlong[: h // 2 - 2, :, 1] > 0.49) and np.all(latlong[h // 2 + 2 :, :, 1] < 0.01)


def test_ground_truth_contains_the_plate():
    """Every plate pixel, looked up in the lat-long by its direction, has the plate's colour."""
    world = smooth_world(1024)
    heading, pitch = 40.0, -8.0
    plate = P.perspective_plate(world, 64, 36, 60.0, heading, pitch, supersample=1)
    latlong = P.ground_truth_latlong(world, P.camera_rotation(heading, pitch), 1024, supersample=1)
    dirs = P.camera_frame_directions(64, 36, 60.0)
    lat = np.arcsin(dirs[..., 1])
    lon = np.arctan2(dirs[..., 0], dirs[..., 2])
    x = np.floor((0.5 - lon / (2 * math.pi)) * 1024).astype(int)
    y = np.floor((0.5 - lat / math.pi) * 512).astype(int)
    np.testing.assert_allclose(latlong[y, x], plate, atol=5e-3)


# --- the committed sample plates ---------------------------------------------------------------


@pytest.mark.parametrize("name", ["courtyard", "city", "sunset"])
def test_sample_plate_files_agree(name):
    oiio = pytest.importorskip("OpenImageIO")
    camera = json.loads((PLATES / f"{name}.json").read_text())
    assert (camera["width"], camera["height"], camera["sensor_fit"]) == (1280, 720, "HORIZONTAL")
    np.testing.assert_allclose(
        camera["camera_rotation_euler"],
        P.camera_rotation_euler(camera["heading_deg"], camera["pitch_deg"], camera["roll_deg"]),
    )
    exr = oiio.ImageBuf(str(PLATES / f"{name}.exr"))
    assert exr.spec().format == oiio.HALF
    assert exr.spec().get_string_attribute("colorInteropID") == "lin_rec709_scene"
    primaries = exr.spec().getattribute("chromaticities")
    np.testing.assert_allclose(primaries, (0.64, 0.33, 0.3, 0.6, 0.15, 0.06, 0.3127, 0.329), 1e-6)
    linear = exr.get_pixels(oiio.FLOAT)
    jpeg = oiio.ImageBuf(str(PLATES / f"{name}.jpg")).get_pixels(oiio.FLOAT)
    assert linear.shape == jpeg.shape == (720, 1280, 3)
    x = np.clip(linear, 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    assert np.abs(encoded - jpeg).mean() < 0.01  # JPEG-quality 92 of the same pixels
