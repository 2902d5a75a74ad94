"""Fifteen more real HDRIs for the 3D study, none of them Blender's: Poly Haven's, as the npm
package @pmndrs/assets ships them (CC0; 512 x 256 equirectangular EXR, DWAB-compressed, each
a base64 `data:` URL in `hdri/<name>.exr.js`).

The package holds 18; three are left out because they are places Blender's bundled HDRIs
already show, where the scenes' sky prior was derived (`DUPLICATES`: the same studio from
another spot, the same sunrise, the same Venice promenade as Blender's sunset). The other 15
are HDRIs nothing in the add-on was chosen on: `--cases polyhaven` draws 30 scenes under them
(`scenes.polyhaven_set`), a second held-out set beside Blender's forest and night.

`ensure()` fetches the package once with the machine's `npm pack` (the npm registry), checks
the tarball against the registry's published integrity (`INTEGRITY`), decodes the 15 files
and keeps them in `folder()` (`$VR_POLYHAVEN_DIR`, else ~/.cache/virtual-reflections/). No
bpy here.
"""

from __future__ import annotations

import base64
import hashlib
import os
import pathlib
import shutil
import subprocess
import tarfile
import tempfile

PACKAGE = "@pmndrs/assets"
VERSION = "1.7.0"
# `npm view @pmndrs/assets@1.7.0 dist.integrity`: the tarball's SHA-512, as the registry gives it
INTEGRITY = (
    "sha512-zHmKNS+3Jvu9K3zJBQfYQKT9Pn9IQt8s0q/eJC3CXKp"
    "Wpyg6IBa+ivN9NgDn+fDT2AVjUh2YRZ//GXUueuAdCg=="
)
NAMES = (
    "apartment",
    "bridge",
    "city",
    "dawn",
    "esplanade",
    "forest",
    "hall",
    "lab",
    "lobby",
    "night",
    "park",
    "sky",
    "sunset",
    "warehouse",
    "workshop",
)
# what an artist would name each shot's surroundings (the panel's Surroundings; as
# `sky_prior.KINDS` for Blender's), by looking at the HDRI: outdoors under an open sky, or a
# room, a hall, a glazed walkway
KINDS = {
    "open": ("city", "dawn", "forest", "night", "park", "sky", "sunset"),
    "enclosed": (
        "apartment",
        "bridge",
        "esplanade",
        "hall",
        "lab",
        "lobby",
        "warehouse",
        "workshop",
    ),
}
# the package's HDRIs of places Blender's bundled ones show: {package name: Blender's}
DUPLICATES = {"studio": "studio", "sunrise": "sunrise", "venice": "sunset"}
PREFIX = "ph_"  # a scene's `hdri` for one of NAMES: "ph_" + name
EXR_MAGIC = b"v/1\x01"
DATA_URL = "data:application/exr;base64,"


class PolyHavenError(Exception):
    """The HDRIs could not be fetched or decoded; one line."""


def folder() -> pathlib.Path:
    """Where the decoded HDRIs are kept."""
    env = os.environ.get("VR_POLYHAVEN_DIR")
    if env:
        return pathlib.Path(env)
    return pathlib.Path.home() / ".cache" / "virtual-reflections" / f"polyhaven-{VERSION}"


def path(name: str) -> pathlib.Path:
    """The EXR of one of NAMES (with or without PREFIX)."""
    name = name.removeprefix(PREFIX)
    if name not in NAMES:
        raise PolyHavenError(f"not one of the study's Poly Haven HDRIs: {name!r}")
    return folder() / f"{name}.exr"


def decode_module(text: str, name: str) -> bytes:
    """The EXR bytes of one `hdri/<name>.exr.js` module (``export default 'data:...'``)."""
    start = text.find(DATA_URL)
    end = text.find("'", start + len(DATA_URL)) if start >= 0 else -1
    if start < 0 or end < 0:
        raise PolyHavenError(f"{name}: no EXR data URL in the package's module")
    try:
        data = base64.b64decode(text[start + len(DATA_URL) : end], validate=True)
    except ValueError as exc:
        raise PolyHavenError(f"{name}: the package's data URL is not base64: {exc}") from exc
    if not data.startswith(EXR_MAGIC):
        raise PolyHavenError(f"{name}: the package's data is not an OpenEXR file")
    return data


def check_integrity(tarball: pathlib.Path, integrity: str = INTEGRITY) -> None:
    """Raise unless ``tarball``'s SHA-512 is the registry's published ``integrity``."""
    digest = base64.b64encode(hashlib.sha512(tarball.read_bytes()).digest()).decode()
    if f"sha512-{digest}" != integrity:
        raise PolyHavenError(
            f"{tarball.name}: its SHA-512 is not the one npm publishes for {PACKAGE}@{VERSION}"
        )


def unpack(tarball: pathlib.Path, target: pathlib.Path) -> None:
    """Decode NAMES from ``tarball`` into ``target``: every file is written beside, checked,
    then moved in, so a failure leaves no partial EXR."""
    target.mkdir(parents=True, exist_ok=True)
    decoded = {}
    with tarfile.open(tarball, "r:gz") as archive:
        for name in NAMES:
            try:
                member = archive.extractfile(f"package/hdri/{name}.exr.js")
            except KeyError:
                member = None
            if member is None:
                raise PolyHavenError(f"{PACKAGE}@{VERSION} has no hdri/{name}.exr.js")
            decoded[name] = decode_module(member.read().decode("ascii", "replace"), name)
    for name, data in decoded.items():
        partial = target / f".{name}.exr.partial"
        partial.write_bytes(data)
        os.replace(partial, target / f"{name}.exr")


def ensure(log=print, npm: str = "npm", integrity: str = INTEGRITY) -> pathlib.Path:
    """The folder holding every HDRI of NAMES, fetched and decoded first if one is missing."""
    target = folder()
    if all((target / f"{name}.exr").is_file() for name in NAMES):
        return target
    exe = shutil.which(npm)
    if exe is None:
        raise PolyHavenError(
            f"the Poly Haven HDRIs need npm to fetch {PACKAGE}@{VERSION} (not found on PATH), "
            f"or set VR_POLYHAVEN_DIR to a folder holding {', '.join(NAMES[:2])}, ... .exr"
        )
    log(f"fetching {PACKAGE}@{VERSION} (Poly Haven HDRIs, CC0) with npm into {target}")
    with tempfile.TemporaryDirectory(prefix="vr_polyhaven_") as tmp:
        try:
            done = subprocess.run(
                [exe, "pack", f"{PACKAGE}@{VERSION}", "--pack-destination", tmp],
                capture_output=True,
                text=True,
                timeout=600,
                check=False,
            )
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise PolyHavenError(f"npm pack {PACKAGE}@{VERSION} failed: {exc}") from exc
        tarballs = sorted(pathlib.Path(tmp).glob("*.tgz"))
        if done.returncode != 0 or len(tarballs) != 1:
            last = (done.stderr.strip().splitlines() or ["no tarball"])[-1]
            raise PolyHavenError(f"npm pack {PACKAGE}@{VERSION} failed: {last}")
        check_integrity(tarballs[0], integrity)
        try:
            unpack(tarballs[0], target)
        except (OSError, tarfile.TarError) as exc:
            raise PolyHavenError(
                f"cannot unpack the Poly Haven HDRIs into {target}: {exc}"
            ) from exc
    return target
