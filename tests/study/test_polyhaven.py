"""The Poly Haven HDRIs of the 3D study (study/polyhaven.py, `--cases polyhaven`), offline: a
fake `npm` hands over a package built here, so the fetch, the integrity check and the decoding
run as they do against the registry; the 30 scenes' draw; two quick scenes rendered under
the folder's HDRIs; the pooled table; the sky prior's derivation on them. (A command line
without npm: tests/study/test_boundary.py.)"""

import base64
import hashlib
import io
import pathlib
import sys
import tarfile

import numpy as np
import pytest

from study import polyhaven
from study.scenes3d import scenes
from virtual_reflections.imagefiles import read_rgba, write_rgba

ROOT = pathlib.Path(__file__).resolve().parents[2]


def exr_bytes(tmp_path, value) -> bytes:
    path = tmp_path / f"tiny{value}.exr"
    pixels = np.full((4, 8, 4), value, np.float32)
    write_rgba(str(path), pixels)
    return path.read_bytes()


def module(data: bytes) -> str:
    return "export default 'data:application/exr;base64," + base64.b64encode(data).decode() + "'"


def package(tmp_path, names=polyhaven.NAMES) -> tuple:
    """A tarball laid out as @pmndrs/assets is, each HDRI a tiny EXR of its own value; returns
    (its path, its npm integrity, {name: value})."""
    values = {name: 0.1 * (i + 1) for i, name in enumerate(names)}
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as archive:
        for name, value in values.items():
            text = module(exr_bytes(tmp_path, value)).encode()
            info = tarfile.TarInfo(f"package/hdri/{name}.exr.js")
            info.size = len(text)
            archive.addfile(info, io.BytesIO(text))
    tarball = tmp_path / "pmndrs-assets.tgz"
    tarball.write_bytes(buffer.getvalue())
    digest = base64.b64encode(hashlib.sha512(buffer.getvalue()).digest()).decode()
    return tarball, f"sha512-{digest}", values


def fake_npm(tmp_path, tarball) -> pathlib.Path:
    """An `npm` that answers `npm pack SPEC --pack-destination DIR` with ``tarball``."""
    exe = tmp_path / "bin" / "npm"
    exe.parent.mkdir(parents=True)
    exe.write_text(
        f"#!{sys.executable}\n"
        "import shutil, sys\n"
        "args = sys.argv[1:]\n"
        "assert args[0] == 'pack' and args[1] == '@pmndrs/assets@1.7.0', args\n"
        f"shutil.copy({str(tarball)!r}, args[args.index('--pack-destination') + 1])\n"
    )
    exe.chmod(0o755)
    return exe


def test_a_module_decodes_to_its_exr_and_anything_else_is_refused(tmp_path):
    data = exr_bytes(tmp_path, 0.5)
    assert polyhaven.decode_module(module(data), "park") == data
    with pytest.raises(polyhaven.PolyHavenError, match="park: the package's data is not an"):
        polyhaven.decode_module(module(b"\x89PNG\r\n\x1a\n" + data), "park")
    with pytest.raises(polyhaven.PolyHavenError, match="no EXR data URL"):
        polyhaven.decode_module("export default 'data:image/png;base64,AAAA'", "park")


def test_ensure_fetches_checks_and_decodes_every_hdri(tmp_path, monkeypatch):
    tarball, integrity, values = package(tmp_path)
    target = tmp_path / "hdris"
    monkeypatch.setenv("VR_POLYHAVEN_DIR", str(target))
    said = []
    assert polyhaven.ensure(said.append, npm=str(fake_npm(tmp_path, tarball)), integrity=integrity)
    assert len(said) == 1 and "@pmndrs/assets@1.7.0" in said[0]
    for name, value in values.items():
        pixels = read_rgba(str(polyhaven.path(name)))
        assert pixels.shape == (4, 8, 4) and np.allclose(pixels[..., :3], value, atol=1e-3)
    assert polyhaven.path("ph_lab") == target / "lab.exr"
    assert not list(target.glob(".*"))  # no partial file left
    said.clear()  # all present: no second fetch
    assert polyhaven.ensure(said.append, npm="no-such-npm", integrity=integrity) == target
    assert said == []


def test_a_tarball_that_is_not_the_published_one_writes_nothing(tmp_path, monkeypatch):
    tarball, integrity, _ = package(tmp_path)
    target = tmp_path / "hdris"
    monkeypatch.setenv("VR_POLYHAVEN_DIR", str(target))
    npm = str(fake_npm(tmp_path, tarball))
    with pytest.raises(polyhaven.PolyHavenError, match="SHA-512 is not the one npm publishes"):
        polyhaven.ensure(lambda line: None, npm=npm, integrity=integrity[:-4] + "AAA=")
    assert not target.exists() or not any(target.iterdir())
    # a package without one of the HDRIs: refused before any file is written
    short, short_integrity, _ = package(tmp_path, polyhaven.NAMES[:-1])
    with pytest.raises(polyhaven.PolyHavenError, match="has no hdri/workshop.exr.js"):
        polyhaven.ensure(
            lambda line: None, npm=str(fake_npm(tmp_path / "x", short)), integrity=short_integrity
        )
    assert not target.exists() or not any(target.iterdir())


def test_the_hdris_are_none_of_blenders_and_each_has_a_kind():
    assert len(polyhaven.NAMES) == 15 and not set(polyhaven.NAMES) & set(polyhaven.DUPLICATES)
    kinds = [name for names in polyhaven.KINDS.values() for name in names]
    assert sorted(kinds) == sorted(polyhaven.NAMES)  # each once: an artist's answer
    with pytest.raises(polyhaven.PolyHavenError, match="not one of"):
        polyhaven.path("ph_venice")  # Blender's sunset promenade: left out


def test_the_polyhaven_scenes_put_two_shapes_under_each_hdri():
    ph = scenes.polyhaven_set()
    assert len(ph) == 30 and [s.to_json() for s in ph] == [
        s.to_json() for s in scenes.polyhaven_set()
    ]
    assert {s.hdri for s in ph} == {polyhaven.PREFIX + n for n in polyhaven.NAMES}
    for name in polyhaven.NAMES:
        shapes = [s.shape for s in ph if s.hdri == polyhaven.PREFIX + name]
        assert len(shapes) == 2 and shapes[0] != shapes[1]
    assert {s.shape for s in ph} == set(scenes.SHAPES)
    others = scenes.scene_set() + scenes.more_set() + scenes.held_out_set()
    assert not {s.seed for s in ph} & {s.seed for s in others}
    for s in ph:  # drawn from the same ranges as the training scenes
        assert 1.4 <= s.camera_height <= 1.8 and 2 <= s.pitch_deg <= 15
        assert 24 <= s.lens_mm <= 85 and 3 <= s.distance <= 10 and 0.3 <= s.size <= 1.5
    assert [s.name for s in scenes.polyhaven_set(quick=True)] == [s.name for s in ph[:2]]


def test_the_quick_polyhaven_scenes_render_under_the_folders_hdris(tmp_path, monkeypatch):
    """The scenes' domes come from VR_POLYHAVEN_DIR (here each name a copy of one of Blender's
    HDRIs: no network), and each scene's Surroundings named by `polyhaven.KINDS`."""
    pytest.importorskip("bpy", reason="the 3D study renders with the bpy module")
    from study.evaluate import hdri_dir
    from study.scenes3d import run_command

    bundled = sorted(hdri_dir().glob("*.exr"))
    folder = tmp_path / "hdris"
    folder.mkdir()
    for i, name in enumerate(polyhaven.NAMES):
        (folder / f"{name}.exr").write_bytes(bundled[i % len(bundled)].read_bytes())
    monkeypatch.setenv("VR_POLYHAVEN_DIR", str(folder))
    data, _ = run_command(
        quick=True,
        cases="polyhaven",
        mirror_only=True,
        cache=tmp_path / "cache",
        surroundings="artist",
        log=lambda _: None,
    )
    assert [r["scene"]["hdri"] for r in data["scenes"]] == ["ph_apartment", "ph_bridge"]
    assert [r["surroundings"] for r in data["scenes"]] == ["ENCLOSED", "ENCLOSED"]
    for record in data["scenes"]:
        scores = record["results"]["mirror"]
        assert all(np.isfinite(s["psnr"]) and np.isfinite(s["ssim"]) for s in scores.values())
    assert "--cases polyhaven --mirror-only --surroundings artist" in data["command"]


def record(hdri, ours, mean, ssim_ours=0.4, ssim_mean=0.2):
    return {
        "scene": {"hdri": hdri},
        "results": {
            "mirror": {
                "Ours": {"psnr": ours, "ssim": ssim_ours},
                "Plate mean": {"psnr": mean, "ssim": ssim_mean},
            }
        },
    }


def test_the_pooled_table_pools_the_sets_and_the_unseen_ones():
    from study.scenes3d import pooled

    def run(*records):
        return {"addon_methods": ["Ours"], "baselines": ["Plate mean"], "scenes": list(records)}

    runs = {
        "default": run(record("city", 13.0, 12.0), record("studio", 14.0, 15.0)),
        "heldout": run(record("forest", 15.0, 13.0)),
        "polyhaven": run(record("ph_lab", 12.0, 11.0), record("ph_sky", 16.0, 13.0)),
    }
    lines = pooled.pooled_table(runs).splitlines()
    assert lines[2].startswith("| the 16 scenes") and "| 2 | 2 | +0.00 (1.00) |" in lines[2]
    assert "| 1/2 (50 %) | 2/2 |" in lines[2]
    unseen = next(line for line in lines if line.startswith("| forest, night and Poly Haven"))
    assert "| 3 | 3 | +2.00 (0.58) | +0.200 | 3/3 (100 %) |" in unseen  # 2, 1, 3 dB
    everything = next(line for line in lines if line.startswith("| all |"))
    assert "| 5 | 5 | +1.20 (0.66) |" in everything and "| 4/5 (80 %) | 5/5 |" in everything


def test_the_sky_prior_derivation_runs_on_them_with_their_negative_pixels_cleared(
    tmp_path, monkeypatch
):
    from study import sky_prior

    h, w = 32, 64
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    for i, name in enumerate(polyhaven.NAMES):  # sky (1 + i) times brighter than the ground
        rgba = np.ones((h, w, 4), np.float32) * 0.2
        rgba[lat > 0, :, :3] = 0.2 * (1 + i)
        rgba[-1, 0, :3] = -0.05  # a lossy codec's undershoot
        write_rgba(str(tmp_path / f"{name}.exr"), rgba)
    monkeypatch.setenv("VR_POLYHAVEN_DIR", str(tmp_path))
    images = sky_prior.load_polyhaven(log=lambda line: None)
    assert sorted(images) == sorted(polyhaven.NAMES)
    assert all(image.min() >= 0 and image.shape == (h, w, 3) for image in images.values())
    gains = sky_prior.polyhaven_gains(images, {})
    # each HDRI's own best gain is its sky over its ground's level (the grid's 0.1 steps;
    # at most 5.0); the summed error's lies between the smallest and the largest
    for i, name in enumerate(polyhaven.NAMES):
        assert gains["own"][name] == pytest.approx(min(1 + i, 5.0), abs=0.15)
    assert 1.0 < gains["alone"] < 5.0 and gains["with_train"] == gains["alone"]


def test_the_pooled_table_holds_the_worst_scene_flip_and_the_upper_half_detail():
    """Issue 41, item 1 in the main mirror table: per set the default's worst scene against the
    plate mean, the mean FLIP of the default and of the plate mean, and the median detail ratio
    of the default's upper half; records scored before those metrics read as "–"."""
    from study.scenes3d import pooled

    def scored(hdri, ours, mean, flips, upper):
        r = record(hdri, ours, mean)
        r["results"]["mirror"]["Ours"].update(flip=flips[0], detail_upper=upper)
        r["results"]["mirror"]["Plate mean"].update(flip=flips[1], detail_upper=0.0)
        return r

    def run(*records):
        return {"addon_methods": ["Ours"], "baselines": ["Plate mean"], "scenes": list(records)}

    runs = {
        "default": run(
            scored("city", 13.0, 12.0, (0.4, 0.6), 0.2),
            scored("studio", 14.0, 15.5, (0.5, 0.5), 0.3),
            scored("sunset", 14.0, 13.0, (0.6, 0.7), 0.7),
        ),
        "heldout": run(record("forest", 15.0, 13.0)),  # before the metrics
    }
    lines = pooled.pooled_table(runs).splitlines()
    assert "worst scene" in lines[0] and "FLIP" in lines[0] and "upper-half detail" in lines[0]
    assert lines[2].endswith("| -1.50 | 0.500 / 0.600 | 0.30 |")
    assert lines[3].endswith("| +2.00 | – / – | – |")
    everything = next(line for line in lines if line.startswith("| all |"))
    assert everything.endswith("| -1.50 | 0.500 / 0.600 | 0.30 |")
