"""The fast mirror loop (`python -m study scenes --mirror-only`) on the quick subset: a first run
renders the plate, the truth, the plate mean and the default method; a second run finds the
first three in the cache and renders only the method, with the same scores; `--sky-gain`
changes the method's maps and nothing else; `--split` says where the method's error lies;
`--surroundings artist` names each scene's Surroundings by the kind of its HDRI; `--surroundings
world` reads the scene's dome from its world as the on-set HDRI.
About 50 s on two cores (bpy 4.5); skipped only when bpy cannot be imported."""

import math
import pathlib
import subprocess
import sys

import pytest

from study.scenes3d import QUICK
from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

ROOT = pathlib.Path(__file__).resolve().parents[2]
LABEL = "Camera View + Ground"


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("mirror_cache")


@pytest.fixture(scope="module")
def runs(tmp_path_factory, cache):
    pytest.importorskip("bpy", reason="the 3D study renders with the bpy module")
    from study.scenes3d import run_command

    out = tmp_path_factory.mktemp("mirror_out")
    first, _ = run_command(quick=True, mirror_only=True, cache=cache, out=out, log=lambda _: None)
    again, _ = run_command(quick=True, mirror_only=True, cache=cache, log=lambda _: None)
    dark, _ = run_command(
        quick=True, mirror_only=True, cache=cache, sky_gain=0.0, log=lambda _: None
    )
    split, _ = run_command(
        quick=True, mirror_only=True, cache=cache, split=True, log=lambda _: None
    )
    named, _ = run_command(
        quick=True, mirror_only=True, cache=cache, surroundings="artist", log=lambda _: None
    )
    world, _ = run_command(
        quick=True, mirror_only=True, cache=cache, surroundings="world", log=lambda _: None
    )
    return first, again, dark, out, split, named, world


def test_the_first_run_renders_four_and_the_second_only_the_method(runs):
    first, again, _, out, _, _, _ = runs
    assert len(first["scenes"]) == len(QUICK.specs())
    assert [r["renders"] for r in first["scenes"]] == [4] * len(QUICK.specs())
    assert [r["renders"] for r in again["scenes"]] == [1] * len(QUICK.specs())
    assert all(r["cached"] for r in again["scenes"]) and not any(
        r["cached"] for r in first["scenes"]
    )
    assert first["addon_methods"] == [LABEL]
    assert (out / "scenes3d_mirror_quick.json").stat().st_size > 500


def test_the_table_gives_the_mean_difference_and_its_standard_error(runs):
    from study.scenes3d import mirror

    first = runs[0]
    diffs = [
        r["results"]["mirror"][LABEL]["psnr"] - r["results"]["mirror"]["Plate mean"]["psnr"]
        for r in first["scenes"]
    ]
    mean = sum(diffs) / len(diffs)
    se = math.sqrt(sum((d - mean) ** 2 for d in diffs) / (len(diffs) - 1) / len(diffs))
    assert f"mean difference {mean:+.2f} dB (standard error {se:.2f})" in mirror.table(first)


def test_width_and_samples_set_the_renders(runs, tmp_path):
    """--width / --samples: the same scenes rendered smaller (the subject's pixels about a
    quarter at half the width), cached apart from the set's own size, and said in the record's
    command. (A cache of its own: the oracle tests find their scenes' folders by name.)"""
    from study.scenes3d import run_command

    first = runs[0]
    small, _ = run_command(
        quick=True, mirror_only=True, cache=tmp_path, width=128, samples=4, log=lambda _: None
    )
    assert small["resolution"] == [128, 72] and small["samples"] == 4
    assert small["command"].endswith("--mirror-only --width 128 --samples 4")
    assert all(r["renders"] == 4 for r in small["scenes"])
    again, _ = run_command(quick=True, mirror_only=True, cache=tmp_path, log=lambda _: None)
    assert all(r["renders"] == 4 for r in again["scenes"])  # the set's size: not those renders
    assert len(list(tmp_path.iterdir())) == 2 * len(small["scenes"])
    for a, b in zip(first["scenes"], small["scenes"]):
        ratio = b["subject_pixels"] / a["subject_pixels"]
        assert 0.1 < ratio < 0.25, ratio  # (128 / 256)^2 = 0.25 less the edges


def test_cached_renders_score_as_the_fresh_ones(runs):
    first, again, _, _, _, _, _ = runs
    for a, b in zip(first["scenes"], again["scenes"]):
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        assert ra["(plate itself)"] == rb["(plate itself)"]
        assert abs(ra[LABEL]["psnr"] - rb[LABEL]["psnr"]) < 0.05
        assert all(math.isfinite(ra[LABEL][m]) for m in ("psnr", "ssim", "si_rmse"))
        # the method is not the plate: an empty render would score exactly the plate
        assert ra[LABEL] != ra["(plate itself)"]


def test_a_black_sky_prior_changes_only_the_method(runs):
    first, _, dark, _, _, _, _ = runs
    assert dark["sky_gain"] == 0.0 and "--sky-gain 0" in dark["command"]
    changed = 0
    for a, b in zip(first["scenes"], dark["scenes"]):
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        changed += abs(ra[LABEL]["psnr"] - rb[LABEL]["psnr"]) > 0.1
    assert changed >= 1  # the quick scenes' plates do not show all their sky


def test_the_split_adds_up_to_the_scores(runs):
    """`--split`: one more render a scene (the sky prior black); the error on the pixels the
    prior sets and on the rest add up to the MSE of the PSNR the loop reports."""
    first, _, _, _, split, _, _ = runs
    assert "--split" in split["command"]
    assert [r["renders"] for r in split["scenes"]] == [2] * len(QUICK.specs())
    for a, b in zip(first["scenes"], split["scenes"]):
        parts = b["split"]
        assert 0.0 < parts["sky_share"] < 1.0  # the quick scenes' plates do not show all their sky
        for name in (LABEL, "Plate mean"):
            mse = parts[name]["sky"] + parts[name]["rest"]
            psnr = b["results"]["mirror"][name]["psnr"]
            assert abs(-10 * math.log10(mse) - psnr) < 1e-3
            assert parts[name]["sky"] > 0 and parts[name]["rest"] > 0
            # a mean squared error is its level plus the variance of the difference
            assert 0 <= parts[name]["sky_level"] <= parts[name]["sky"] + 1e-12
        assert parts["truth_spread"] > 0
        assert (
            abs(a["results"]["mirror"][LABEL]["psnr"] - b["results"]["mirror"][LABEL]["psnr"])
            < 0.05
        )


def test_the_split_scores_every_level_of_the_prior(runs):
    """`--split` also keeps each scene's mirror PSNR over the plate mean at every scale of the
    prior (its part of the render is linear in it) and the band's levels; at scale 1 the curve
    is the rendered difference, at its smallest near the black prior's, and the level
    statistic's table gives the run's own mean difference on the add-on's exponent
    (docs/scenes3d.md, "The level's statistic")."""
    from study.scenes3d import prior_level

    _, _, dark, _, split, _, _ = runs
    assert prior_level.SCALES[50] == pytest.approx(1.0)
    differences = []
    for b, d in zip(split["scenes"], dark["scenes"]):
        mirror = b["results"]["mirror"]
        curve = b["split"]["prior_scales"]
        assert len(curve) == len(prior_level.SCALES)
        difference = mirror[LABEL]["psnr"] - mirror["Plate mean"]["psnr"]
        assert curve[50] == pytest.approx(difference, abs=1e-6)
        differences.append(difference)
        # the smallest scale nears the render with the prior black (--sky-gain 0)
        black = d["results"]["mirror"][LABEL]["psnr"] - mirror["Plate mean"]["psnr"]
        assert abs(curve[0] - black) < abs(curve[50] - black)
        assert max(curve) > curve[0] and max(curve) > curve[-1]  # neither black nor blinding
        band = b["split"]["band"]
        assert 0 < band["log_average"] < band["mean"]  # a textured ground: the mean is above
    table = prior_level.statistic_table(split)
    line = next(row for row in table.splitlines() if "(the add-on's)" in row)
    assert f"{sum(differences) / len(differences):+.2f} dB" in line, table
    assert len(table.splitlines()) == 2 + len(prior_level.EXPONENTS) + 3
    # the constant gain the scenes would pick scores at least the add-on's on them, and each
    # scene's own best at least that
    gain, best = prior_level.best_constant_gain(split)
    assert best >= sum(differences) / len(differences) - 1e-9 and gain > 0
    assert f"{gain:.1f}, {best:+.2f} dB" in table.splitlines()[-2]
    own = sum(max(b["split"]["prior_scales"]) for b in split["scenes"]) / len(split["scenes"])
    assert own >= best - 1e-9
    assert f"{own:+.2f} dB" in table.splitlines()[-1]
    assert "Auto gain only" in prior_level.statistic_table(dark)


def test_the_split_scores_the_prior_tinted(runs):
    """`--split` also keeps each scene's mirror PSNR over the plate mean with the prior tinted
    toward the plate's mean colour (its part of the render is linear in each channel): the
    neutral tint is the rendered difference, a tint changes it, and the colour table's first
    row is the run's own mean (docs/scenes3d.md, "The prior's colour and the plate's mean")."""
    from study.scenes3d import prior_colour

    _, _, dark, _, split, _, _ = runs
    assert prior_colour.TINTS[0] == 0.0
    firsts = []
    for b in split["scenes"]:
        mirror = b["results"]["mirror"]
        tints = b["split"]["tints"]
        assert len(tints) == len(prior_colour.TINTS)
        difference = mirror[LABEL]["psnr"] - mirror["Plate mean"]["psnr"]
        assert tints[0] == pytest.approx(difference, abs=1e-6)
        assert tints[-1] != pytest.approx(tints[0], abs=1e-4)  # the plates are not grey
        firsts.append(tints[0])
    table = prior_colour.colour_table(split)
    line = next(row for row in table.splitlines() if "(the add-on's)" in row)
    assert f"{sum(firsts) / len(firsts):+.2f} dB" in line, table
    assert "Auto gain only" in prior_colour.colour_table(dark)


def test_the_artist_names_each_scenes_surroundings_by_its_hdri(runs):
    """The quick subset is a city (open sky) and an interior (enclosed): each scene's panel
    setting is its kind, the plate mean is untouched and the method's maps change."""
    from study.sky_prior import KINDS

    first, _, _, _, _, named, _ = runs
    assert named["surroundings"] == "artist" and "--surroundings artist" in named["command"]
    assert {r["surroundings"] for r in first["scenes"]} == {"AUTO"}
    kinds = [r["surroundings"] for r in named["scenes"]]
    assert sorted(kinds) == ["ENCLOSED", "OPEN"]
    for a, b in zip(first["scenes"], named["scenes"]):
        assert b["scene"]["hdri"] in KINDS[b["surroundings"].lower()]
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        assert abs(ra[LABEL]["psnr"] - rb[LABEL]["psnr"]) > 0.1


def test_the_world_hdri_beats_the_guessed_sky(runs):
    """`--surroundings world`: the scene's dome, read from its world as an on-set HDRI, in
    place of the guessed sky; in each quick scene the mirror comes closer to the truth than
    under Auto (the plate mean untouched)."""
    first, _, _, _, _, _, world = runs
    assert {r["surroundings"] for r in world["scenes"]} == {"WORLD"}
    for a, b in zip(first["scenes"], world["scenes"]):
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        assert rb[LABEL]["psnr"] > ra[LABEL]["psnr"] + 1.0, (ra[LABEL], rb[LABEL])
        assert rb[LABEL]["ssim"] > ra[LABEL]["ssim"]


@pytest.fixture(scope="module")
def oracle_runs(runs, cache):
    """Both oracles on the quick subset, from the cache `runs` filled; the shadow oracle twice
    (the second finds its shadowed plates in the cache)."""
    from study.scenes3d import run_command

    def oracle(name):
        data, _ = run_command(
            quick=True, mirror_only=True, cache=cache, oracle=name, log=lambda _: None
        )
        return data

    return oracle("shadow"), oracle("shadow"), oracle("proxies")


def test_the_shadow_oracle_puts_the_subjects_shadow_in_the_plate(runs, cache, oracle_runs):
    """`--oracle shadow`: the plate rendered again with the subject hidden from the camera
    only darkens the ground around it (its shadow), is cached, and Generate on it gives a row
    of its own (the plate mean untouched)."""
    from study.scenes3d import oracles

    first = runs[0]
    shadow, again, _ = oracle_runs
    row = f"{LABEL} (shadow in the plate)"
    assert [r["renders"] for r in shadow["scenes"]] == [3] * len(QUICK.specs())
    assert [r["renders"] for r in again["scenes"]] == [2] * len(QUICK.specs())
    for a, b in zip(first["scenes"], shadow["scenes"]):
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        assert math.isfinite(rb[row]["psnr"]) and rb[row] != rb[LABEL]
        folder = next(cache.glob(f"{a['scene']['name']}-*"))
        plate = oracles.shadow_plate(folder).sum(-1)
        before = srgb_to_linear(read_rgba(str(folder / "plate.png"))[..., :3]).sum(-1)
        darker, brighter = (before - plate > 0.03).sum(), (plate - before > 0.03).sum()
        assert darker > 30 and darker > 3 * brighter, (darker, brighter)


def test_the_proxy_oracle_traces_the_mirror_without_and_with_the_boxes(runs, oracle_runs):
    """`--oracle proxies`: the ray-traced pass shows the Suzanne in itself (s103 changes over
    one pass), and the scene's boxes put back for the mirror's rays change what it shows."""
    first = runs[0]
    proxies = oracle_runs[2]
    traced, boxes = f"{LABEL} (traced)", f"{LABEL} (traced, true proxies)"
    assert [r["renders"] for r in proxies["scenes"]] == [3] * len(QUICK.specs())
    for a, b in zip(first["scenes"], proxies["scenes"]):
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        assert all(math.isfinite(rb[name]["psnr"]) for name in (traced, boxes))
        assert rb[boxes] != rb[traced], a["scene"]["name"]
        if "suzanne" in a["scene"]["name"]:
            assert abs(rb[traced]["psnr"] - rb[LABEL]["psnr"]) > 0.02, (rb[traced], rb[LABEL])


def test_cache_and_sky_gain_need_mirror_only_in_one_line():
    for extra in (
        ["--cache", "/tmp/x"],
        ["--split"],
        ["--oracle", "shadow"],
        ["--mirror-only", "--oracle", "sun"],
        ["--surroundings", "open"],
        ["--mirror-only", "--sky-gain", "-1"],
        ["--mirror-only", "--sky-gain", "1", "--surroundings", "open"],
        ["--mirror-only", "--surroundings", "outdoors"],
        ["--width", "640"],
        ["--samples", "64"],
        ["--mirror-only", "--width", "10"],
        ["--mirror-only", "--samples", "0"],
    ):
        r = subprocess.run(
            [sys.executable, "-m", "study", "scenes", "--quick", *extra],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_the_contact_shadow_option_sets_the_panels_strength(runs, cache):
    """--contact-shadow 0: the panel's Contact Shadow off in every scene; the subject's lowest
    part then reflects the plate's ground as it is, so the method's scores change and nothing
    else does; the record's command says so; out of 0..1 it is refused."""
    from study.scenes3d import ScenesInputError, run_command

    first = runs[0]
    off, _ = run_command(
        quick=True, mirror_only=True, cache=cache, contact_shadow=0.0, log=lambda _: None
    )
    assert off["command"].endswith("--mirror-only --contact-shadow 0")
    assert off["contact_shadow"] == 0.0
    changed = 0
    for a, b in zip(first["scenes"], off["scenes"]):
        ra, rb = a["results"]["mirror"], b["results"]["mirror"]
        assert ra["Plate mean"] == rb["Plate mean"]
        changed += abs(ra[LABEL]["psnr"] - rb[LABEL]["psnr"]) > 0.01
    assert changed >= 1
    with pytest.raises(ScenesInputError, match="--contact-shadow: 0..1"):
        run_command(quick=True, mirror_only=True, cache=cache, contact_shadow=1.5)
    with pytest.raises(ScenesInputError, match="go with --mirror-only"):
        run_command(quick=True, contact_shadow=0.5)
