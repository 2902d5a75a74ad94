"""The accuracy study: metrics on cases with known answers, probe spheres whose picture is known,
the ground truth, and the claims docs/accuracy.md makes, checked on the quick subset."""

import math

import numpy as np
import pytest

from study import cli
from study.evaluate import baselines as B
from study.evaluate import metrics as M
from study.evaluate import spheres as S
from study.evaluate import study

RNG = np.random.default_rng(5)


def hdris_available():
    try:
        folder = study.hdri_dir()
    except FileNotFoundError:
        return False
    return all((folder / f"{n}.exr").is_file() for n in study.QUICK.hdris)


needs_hdris = pytest.mark.skipif(
    not hdris_available(),
    reason="Blender's studio-light HDRIs not found (bpy wheel or VR_HDRI_DIR)",
)


def map_of(colour_of_direction, width=128):
    """A camera-frame lat-long `(W/2, W, 3)` whose texel centres hold colour(direction)."""
    return colour_of_direction(S.latlong_directions(width)).astype(np.float32)


# --- metrics --------------------------------------------------------------------------------


def test_identical_images_score_perfectly():
    img = RNG.random((32, 32, 3)).astype(np.float32)
    assert M.psnr(img, img) == math.inf
    assert M.ssim(img, img) == pytest.approx(1.0)
    assert M.si_rmse(img, img) == pytest.approx(0.0, abs=1e-7)
    assert M.angular_error(img, img) == pytest.approx(0.0, abs=1e-3)


def test_known_metric_values():
    truth = np.full((8, 8, 3), 0.5)
    assert M.psnr(truth + 0.1, truth) == pytest.approx(20.0)  # MSE 0.01
    assert M.psnr(truth + 0.01, truth) == pytest.approx(40.0)
    # scale invariance: a darker copy is perfect for si-RMSE and angular error, not for PSNR
    assert M.si_rmse(0.25 * truth, truth) == pytest.approx(0.0, abs=1e-12)
    assert M.angular_error(0.25 * truth, truth) == pytest.approx(0.0, abs=1e-3)
    assert M.si_rmse(np.zeros_like(truth), truth) == pytest.approx(1.0)
    red, green = np.zeros((4, 4, 3)), np.zeros((4, 4, 3))
    red[..., 0], green[..., 1] = 1.0, 1.0
    assert M.angular_error(red, green) == pytest.approx(90.0)
    assert M.angular_error(red + green, red) == pytest.approx(45.0)
    # a mask restricts every metric to its pixels
    pred = truth.copy()
    pred[:4] += 0.1
    mask = np.zeros((8, 8), bool)
    mask[4:] = True
    assert M.psnr(pred, truth, mask) == math.inf
    assert M.psnr(pred, truth, ~mask) == pytest.approx(20.0)


def test_ssim_falls_with_noise_and_structure():
    img = RNG.random((64, 64, 3))
    slightly = np.clip(img + 0.02 * RNG.standard_normal(img.shape), 0, 1)
    badly = np.clip(img + 0.3 * RNG.standard_normal(img.shape), 0, 1)
    flat = np.full_like(img, img.mean())
    assert 1.0 > M.ssim(slightly, img) > M.ssim(badly, img)
    assert M.ssim(flat, img) < 0.1
    assert M.ssim(slightly, img) == pytest.approx(M.ssim(img, slightly))


def test_plate_view_mask_is_what_the_plate_sees():
    """The texels the plate sees: their share of the sphere is the plate's solid angle
    (4 asin(sin a sin b) for half-angles a, b), less the one-texel margin."""
    width, w, h, hfov = 512, 640, 360, 60.0
    mask = M.plate_view_mask(width, w, h, hfov)
    half_h = math.radians(hfov) / 2
    half_v = math.atan(math.tan(half_h) * h / w)
    view = 4 * math.asin(math.sin(half_h) * math.sin(half_v))
    seen = float((mask * S.row_solid_angles(width // 2)[:, None]).sum())
    assert 0.75 * view < seen < view
    assert mask[width // 4, width // 2]  # straight ahead
    assert not mask[width // 4, 0]  # behind the camera
    assert not mask[2, width // 2]  # the zenith


# --- spheres --------------------------------------------------------------------------------


def test_constant_map_gives_constant_spheres():
    env = np.full((64, 128, 3), [0.2, 0.4, 0.8], np.float32)
    mask = S.sphere_mask(48)
    for render in (S.mirror_sphere, S.glossy_sphere, S.diffuse_sphere, S.diffuse_sphere_exact):
        sphere = render(env, 48)
        np.testing.assert_allclose(
            sphere[mask], np.broadcast_to([0.2, 0.4, 0.8], (mask.sum(), 3)), atol=2e-4
        )
        assert np.all(sphere[:4, :4] == 0.0)  # off the sphere: background


def test_left_of_the_map_shows_on_the_spheres_left():
    """+X (the plate's left) red, -X blue: red on the left half of every sphere; up (+Y) bright
    shows on the top."""
    env = map_of(lambda d: np.where(d[..., :1] > 0, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]))
    for render in (S.mirror_sphere, S.glossy_sphere, S.diffuse_sphere):
        sphere = render(env, 64)
        left, right = sphere[24:40, 4:24].mean((0, 1)), sphere[24:40, 40:60].mean((0, 1))
        assert left[0] > 2 * left[2] and right[2] > 2 * right[0], render.__name__
    sky = map_of(lambda d: np.where(d[..., 1:2] > 0, 1.0, 0.1) * np.ones(3))
    sphere = S.mirror_sphere(sky, 64)
    assert sphere[6:20, 28:36].mean() > 0.9 and sphere[44:58, 28:36].mean() < 0.2


def test_mirror_centre_reflects_behind_the_camera_and_rim_behind_the_sphere():
    behind_camera = map_of(lambda d: np.where(d[..., 2:3] < 0, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
    sphere = S.mirror_sphere(behind_camera, 64)
    assert sphere[32, 32, 0] > 0.99  # centre: -Z
    assert sphere[32, 1, 1] > 0.99 and sphere[1, 32, 1] > 0.99  # rim: +Z


def test_object_view_turns_the_sphere_toward_the_object():
    np.testing.assert_allclose(S.object_view([0, 0, 1]), np.eye(3), atol=1e-12)
    d = np.array([0.5, 0.2, 1.0])
    r = S.object_view(d)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(r[:, 2], d / np.linalg.norm(d))
    assert np.linalg.det(r) == pytest.approx(1.0)
    # the centre of a mirror sphere seen along d reflects -d
    env = map_of(lambda x: np.clip(-(x @ (d / np.linalg.norm(d))), 0, 1)[..., None] * np.ones(3))
    assert S.mirror_sphere(env, 65, 1, r)[32, 32, 0] > 0.99


def test_irradiance_of_a_linear_map_is_known():
    """L(w) = a + b.w has irradiance pi a + (2 pi / 3) b.n: SH9 and the exact convolution agree."""
    a, b = 0.5, np.array([0.1, 0.3, -0.2])
    env = map_of(lambda d: (a + d @ b)[..., None] * np.ones(3), 256)
    normals = S.sphere_normals(48)
    mask = S.sphere_mask(48) & (normals[..., 2] < -0.5)  # away from the rim (pixel averages)
    expected = (a + (2.0 / 3.0) * normals @ b)[mask]
    for sphere in (S.diffuse_sphere(env, 48), S.diffuse_sphere_exact(env, 48)):
        np.testing.assert_allclose(sphere[mask][:, 0], expected, atol=5e-3)


def test_probe_matches_the_sphere_functions():
    env = RNG.random((64, 128, 3)).astype(np.float32)
    view = S.object_view([0.3, -0.1, 1.0])
    probe = S.Probe(40, view)
    mirror, glossy, diffuse = probe.render(env)
    np.testing.assert_allclose(mirror, S.mirror_sphere(env, 40, view=view), atol=1e-5)
    np.testing.assert_allclose(glossy, S.glossy_sphere(env, 40, view=view), atol=1e-5)
    np.testing.assert_allclose(diffuse, S.diffuse_sphere(env, 40, view=view), atol=1e-5)


def test_sampling_and_resampling_keep_texels_and_means():
    env = RNG.random((32, 64, 3)).astype(np.float32)
    np.testing.assert_allclose(S.sample_latlong(env, S.latlong_directions(64)), env, atol=1e-5)
    small = S.resample_latlong(env, 16)
    weights = S.row_solid_angles(32)[:, None, None]
    np.testing.assert_allclose(
        (small * S.row_solid_angles(8)[:, None, None]).sum((0, 1)),
        (env * weights).sum((0, 1)),
        rtol=1e-5,
    )


# --- methods and ground truth -----------------------------------------------------------------


def test_baselines_have_the_method_signature():
    plate = RNG.random((90, 160, 3)).astype(np.float32)
    bbox = (60, 30, 100, 70)
    for method in B.BASELINES + (B.Method("paper n=8", "paper", B.paper(8)),):
        env = method.fn(plate, bbox, 60.0, 64)
        assert env.shape == (32, 64, 3) and env.dtype == np.float32, method.name
    np.testing.assert_allclose(B.plate_mean(plate, bbox, 60, 8)[0, 0], plate.mean((0, 1)), 1e-5)
    stretched = B.stretched_plate(plate, bbox, 60.0, 160)
    assert stretched.shape == (80, 160, 3)
    assert abs(stretched.mean() - plate.mean()) < 0.02


def test_ldr_plate_is_an_8bit_srgb_photograph():
    linear = np.array([[[0.0, 0.214, 1.0], [3.0, 0.5, 1e-4]]], np.float32)
    ldr = study.ldr_plate(linear)
    assert ldr.max() <= 1.0 and ldr[0, 1, 0] == 1.0  # clipped
    np.testing.assert_allclose(ldr[0, 0], [0.0, 0.214, 1.0], atol=3e-3)  # quantised
    assert (
        len(
            np.unique(
                study.ldr_plate(
                    np.linspace(0, 1, 10000, dtype=np.float32)[None, :, None]
                    * np.ones(3, np.float32)
                )
            )
        )
        <= 256
    )


def test_placements_are_where_they_say():
    by = {p.name: p.bbox(640, 360) for p in study.PLACEMENTS}
    assert by["left border"][0] < 0 < by["left border"][2]
    assert by["right border"][0] < 640 < by["right border"][2]
    assert by["top border"][1] < 0 and by["bottom border"][3] > 360
    assert by["tiny"][2] - by["tiny"][0] == pytest.approx(18.0)
    x0, y0, x1, y1 = by["centred"]
    assert (x0 + x1) / 2 == 320
    np.testing.assert_allclose(
        study.object_direction((310, 170, 330, 190), (640, 360), 60), [0, 0, 1], atol=1e-12
    )
    d = study.object_direction(by["left border"], (640, 360), 60)
    assert d[0] > 0.4  # the plate's left is +X


def test_auto_map_width_follows_the_object_size():
    assert study.auto_map_width(18) == 256
    assert study.auto_map_width(108) == 512
    assert study.auto_map_width(288) == 1024
    assert study.auto_map_width(5000) == 4096  # the engine's rule (mapsize.py): no clamp at 1024


@needs_hdris
def test_view_is_exposed_and_truth_matches_the_plate():
    view = study.make_view("courtyard", -120.0, -8.0, 60.0, (160, 90), 256)
    lum = view.plates["exr"].astype(np.float64) @ study.LUMA
    assert math.exp(np.mean(np.log(lum + 1e-4))) == pytest.approx(study.KEY, rel=1e-3)
    assert view.truths["ldr"].max() <= 1.0 + 1e-5  # the clipped world, averaged
    # the truth, seen where the plate sees, is the plate (an oracle map built by sampling the
    # plate on the map's texels is within a few percent)
    mask = M.plate_view_mask(256, 160, 90, 60.0)
    d = S.latlong_directions(256)[mask]
    f = 80 / math.tan(math.radians(30))
    px = np.clip((80 - f * d[:, 0] / d[:, 2]).astype(int), 0, 159)
    py = np.clip((45 - f * d[:, 1] / d[:, 2]).astype(int), 0, 89)
    plate_seen = view.plates["exr"][py, px]
    truth_seen = view.truths["hdr"][mask]
    assert M.psnr(M.to_display(plate_seen), M.to_display(truth_seen)) > 22.0


# --- the quick study and the claims of docs/accuracy.md -------------------------------------------


@pytest.fixture(scope="module")
def quick():
    if not hdris_available():
        pytest.skip("Blender's studio-light HDRIs not found (bpy wheel or VR_HDRI_DIR)")
    return study.run_study(study.QUICK, jobs=1)  # serial: safe in any process (bpy imported)


def test_quick_study_measures_every_method_on_every_case(quick):
    cases = len(study.QUICK.hdris) * len(study.QUICK.placements)
    methods = len(quick.methods)
    assert len(quick.records) == cases * methods * len(study.QUICK.comparisons)
    for r in quick.records:
        assert all(np.isfinite(r[k]) for k in study.METRICS)
    assert set(quick.timing) == {m["name"] for m in quick.methods}


def test_quick_study_bounds(quick):
    """What any honest method scores: the plate mean's map is flat, so its plate PSNR is low;
    PSNR and SSIM stay in their ranges."""
    summary = study.summarise(quick)
    for name, s in summary.items():
        assert 0 < s["mirror_psnr"] < 40 and -1 <= s["mirror_ssim"] <= 1, name
        assert 0 <= s["diffuse_si_rmse"] <= 1.0, name
    assert summary["plate mean"]["plate_psnr"] < 25


def test_the_claims_of_the_docs_hold_on_the_quick_subset(quick):
    """docs/accuracy.md lists these claims (study.CLAIMS), measured on the full run; the quick
    subset must agree, or the docs say something the code no longer does."""
    if quick.default is None:
        pytest.skip("no engine method registered in study.methods")
    claims = study.check_claims(quick)
    assert claims, "no claims checked"
    failed = [claim for claim, holds in claims if not holds]
    assert not failed, failed


def test_the_study_refuses_a_pitch_its_horizon_method_does_not_know():
    """The horizon method ("engine camera + horizon") knows the study's pitch only: another
    pitch with the study's own methods is refused before any work, in one line."""
    from dataclasses import replace

    with pytest.raises(ValueError, match="horizon of a -8 degree pitch only, not -20"):
        study.run_study(replace(study.QUICK, pitch=-20.0), jobs=1)


def test_claims_are_in_the_docs():
    import pathlib

    doc = pathlib.Path(__file__).resolve().parents[2] / "docs" / "accuracy.md"
    text = " ".join(doc.read_text().split())
    for claim in study.CLAIMS:
        assert " ".join(claim.__doc__.split()) in text, claim.__name__


# --- the command line -----------------------------------------------------------------------


def test_evaluate_rejects_an_unknown_hdri(capsys):
    assert cli.main(["evaluate", "--quick", "--hdri", "moon"]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown HDRI 'moon'" in err[0]


def test_results_survive_json(quick):
    import json

    back = study.results_from_json(json.loads(json.dumps(study.results_to_json(quick))))
    assert len(back.records) == len(quick.records)
    a, b = study.summarise(quick), study.summarise(back)
    assert all(abs(a[m][k] - b[m][k]) < 1e-3 for m in a for k in a[m])
    assert back.default == quick.default
