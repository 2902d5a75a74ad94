"""The methods' parameters (Params), validated once at the edge; the sky gain by roughness.

Defaults come from the paper (§3.2): enlarge the object's bounds by 5–10 % of the image
size (we take 7.5 %) and keep region X at least 10–20 % (we take 15 %) away from the border.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .camera_view import camera_intrinsics
from .methods import (
    AUTO_SKY_GAIN,
    AUTO_SKY_ROUGHNESS,
    AUTO_SKY_TINT,
    MAX_TRIANGLES,
    METHOD_ALIASES,
    METHOD_NAMES,
    SKY_GAINS,
    SKY_TEXTURE,
    reads_ground,
    uses_camera,
)

METHODS = METHOD_NAMES  # Params.method's names (methods.METHODS); the sky gains: methods.SKY_GAINS
MAX_SKY_GAIN = 100.0  # Params.sky_gain's upper bound
# A map pre-filtered for a rough surface (the Mix look) holds a sky that many times brighter,
# by roughness: a rough lobe carries a light's energy into the directions around it (the same
# study, a ground lit by the sky; tests/study/test_sky_prior.py ties them to it).
ROUGH_SKY_RATIOS = {
    "auto": ((0.15, 1.45), (0.35, 2.73), (0.5, 3.64), (1.0, 11.0)),
    "open": ((0.15, 1.03), (0.35, 1.14), (0.5, 1.17), (1.0, 2.0)),
    "enclosed": ((0.15, 1.5), (0.35, 4.17), (0.5, 7.17), (1.0, 29.33)),
}


def _unit_roughness(roughness: float) -> float:
    """A roughness clamped to 0..1 (NaN counts as 0)."""
    return min(max(float(roughness), 0.0), 1.0) if math.isfinite(roughness) else 0.0


def sky_gain_for(kind: str, roughness: float = 0.0, custom: float | None = None) -> float:
    """The sky prior's gain for named surroundings, seen by a surface of a given roughness.

    SKY_GAINS[kind] times ROUGH_SKY_RATIOS[kind] interpolated linearly in roughness between its
    knots on the logarithm of the ratio (1 at roughness 0), held beyond the last; at most
    MAX_SKY_GAIN.

    Parameters
    ----------
    kind : str
        A key of SKY_GAINS; another (as "world" or "custom") is taken as "auto".
    roughness : float, optional
        0 for a mirror or a map that is not pre-filtered, up to 1 (clamped; NaN counts as 0).
    custom : float, optional
        The mirror's gain the artist set (Surroundings Custom, its Sky Brightness) in place of
        SKY_GAINS[kind]; a rough surface's ratio is then Auto's.

    Returns
    -------
    float
    """
    kind = kind if kind in SKY_GAINS else "auto"
    knots = ((0.0, 1.0), *ROUGH_SKY_RATIOS[kind])
    r = _unit_roughness(roughness)
    xs = [k for k, _ in knots]
    logs = [math.log(v) for _, v in knots]
    base = SKY_GAINS[kind] if custom is None else float(custom)
    return min(base * math.exp(float(np.interp(r, xs, logs))), MAX_SKY_GAIN)


def sky_prior_for(kind: str, roughness: float = 0.0, custom: float | None = None) -> dict:
    """Params' sky prior fields for named surroundings, seen by a surface of a given roughness.

    Auto takes the photo's own mean colour for a mirror (``sky_from_plate`` 1, AUTO_SKY_GAIN,
    its hue AUTO_SKY_TINT of the way from grey) and, from AUTO_SKY_ROUGHNESS on, the ground
    band's sky brighter by ROUGH_SKY_RATIOS["auto"] (`sky_gain_for`), the two blended
    geometrically in between; the other kinds take the ground band's (`sky_gain_for`).

    Parameters
    ----------
    kind : str
        A key of SKY_GAINS; another (as "world", whose HDRI replaces the prior where it can)
        is taken as "auto".
    roughness : float, optional
        As for `sky_gain_for`.
    custom : float, optional
        As for `sky_gain_for` (the prior is then the ground's).

    Returns
    -------
    dict
        ``sky_gain``, ``sky_from_plate`` and ``sky_tint_share``, to pass to `Params`.
    """
    if custom is not None or (kind != "auto" and kind in SKY_GAINS):  # world, unknown: Auto's
        gain = sky_gain_for(kind, roughness, custom)
        return {"sky_gain": gain, "sky_from_plate": 0.0, "sky_tint_share": 0.0}
    r = _unit_roughness(roughness)
    plate = 1.0 - min(r / AUTO_SKY_ROUGHNESS, 1.0)
    gain = AUTO_SKY_GAIN**plate * sky_gain_for("auto", r) ** (1.0 - plate)
    return {
        "sky_gain": min(gain, MAX_SKY_GAIN),
        "sky_from_plate": plate,
        "sky_tint_share": AUTO_SKY_TINT * plate,
    }


def sky_texture_for(share: float, roughness: float = 0.0) -> float:
    """The share of the plate's texture in the unseen sky a surface of some roughness sees.

    The artist's share for a mirror, falling linearly to 0 at AUTO_SKY_ROUGHNESS (where
    Auto's sky, too, is the rough one's): a rough surface's lobe blurs a structure that is
    not the truth's into error (with the texture at every roughness the rough rows of the
    16-scene study lost 0.07-0.12 dB; docs/changelog.md, "The sky's texture").

    Parameters
    ----------
    share : float
        The artist's Sky Texture, 0..1.
    roughness : float, optional
        As for `sky_gain_for`.

    Returns
    -------
    float
        `World.sky_texture`, rounded to 1e-4.
    """
    r = _unit_roughness(roughness)
    return round(float(share) * (1.0 - min(r / AUTO_SKY_ROUGHNESS, 1.0)), 4)


@dataclass(frozen=True)
class Regions:
    """The paper's cut of the plate (§3.2) and its front face (§3.1).

    Every method segments the plate with `enlarge` and `border` (the add-on's advice and
    previews); the paper's method maps the environment through those regions and
    `triangles`. Lengths are fractions of the plate's width/height.

    Parameters
    ----------
    enlarge : float
        Growth of the object's bounding box, 0..1 (paper §3.2: 5-10 %).
    border : float
        Least distance of region X from every plate edge, 0 <= border < 0.5 (paper: 10-20 %).
    triangles : int
        n triangles of the front face (a multiple of 4, 4..MAX_TRIANGLES), or 0 for the
        continuous limit n -> infinity.
    """

    enlarge: float = 0.075
    border: float = 0.15
    triangles: int = 0

    def __post_init__(self):
        if not (math.isfinite(self.enlarge) and 0.0 <= self.enlarge <= 1.0):
            raise ValueError(f"enlarge must be between 0 and 1, got {self.enlarge}")
        if not (math.isfinite(self.border) and 0.0 <= self.border < 0.5):
            raise ValueError(f"border must be at least 0 and below 0.5, got {self.border}")
        n = self.triangles
        if isinstance(n, bool) or not isinstance(n, int):
            raise ValueError(f"triangles must be an integer, got {n!r}")
        if n != 0 and (n % 4 or not 4 <= n <= MAX_TRIANGLES):
            raise ValueError(
                f"triangles must be 0 (continuous) or a multiple of 4 from 4 to "
                f"{MAX_TRIANGLES}, got {n}"
            )


@dataclass(frozen=True)
class Lens:
    """The plate camera, which the camera-view methods place the plate by.

    Parameters
    ----------
    hfov : float or None
        The horizontal field of view in degrees (0..180) of a centred pinhole.
    intrinsics : (fx, fy, cx, cy) or None
        The camera in plate pixels (lens shift, pixel aspect); overrides `hfov`.
    """

    hfov: float | None = None
    intrinsics: tuple | None = None

    def __post_init__(self):
        if self.hfov is not None and not (math.isfinite(self.hfov) and 0.0 < self.hfov < 180.0):
            raise ValueError(f"hfov must be between 0 and 180 degrees, got {self.hfov}")
        if self.intrinsics is not None and (
            len(self.intrinsics) != 4
            or not all(math.isfinite(v) for v in self.intrinsics)
            or self.intrinsics[0] <= 0
            or self.intrinsics[1] <= 0
        ):
            raise ValueError(f"intrinsics must be (fx > 0, fy > 0, cx, cy), got {self.intrinsics}")

    @property
    def known(self) -> bool:
        """Whether the camera is given (`hfov` or `intrinsics`)."""
        return self.hfov is not None or self.intrinsics is not None

    def at(self, width: int, height: int) -> tuple:
        """The camera's intrinsics on a plate of this size (camera_view.camera_intrinsics).

        Parameters
        ----------
        width, height : int
            The plate's size in pixels.

        Returns
        -------
        tuple of 4 floats
            (fx, fy, cx, cy) in plate pixels.
        """
        return camera_intrinsics(width, height, self.hfov, self.intrinsics)


@dataclass(frozen=True)
class Extend:
    """The camera view's edge extension outside the plate's view (extension.py).

    Parameters
    ----------
    blur : float
        Pixels of blur per pixel of angular distance from the plate's view, 0..100.
    cap : float
        The blur's cap as a share of the plate height, (0..1].
    fade : float or None
        Degrees from the plate's view over which the extension fades (a smoothstep in angle)
        into the fill, 0..180; None extends the edges everywhere (20: docs/accuracy.md).
    """

    blur: float = 1.0
    cap: float = 0.125
    fade: float | None = 20.0

    def __post_init__(self):
        if not (0.0 <= self.blur <= 100.0 and 0.0 < self.cap <= 1.0):
            raise ValueError("extend_blur must be in [0, 100] and extend_cap in (0, 1]")
        if self.fade is not None and not (math.isfinite(self.fade) and 0.0 <= self.fade <= 180.0):
            raise ValueError(f"extend_fade must be None or 0..180 degrees, got {self.fade}")


@dataclass(frozen=True)
class Fill:
    """The camera view's fill where the plate shows nothing: profiles by elevation (fill.py).

    Parameters
    ----------
    width : float
        Half-width of the elevation window the fill averages, 0.5..90 degrees.
    saturation : float
        How much of the plate's colour the fill keeps, 0 (grey of the same luminance)..1; with
        `sides`, of the tint both sides share (their difference is kept).
    spread : float
        Degrees of half-width per degree beyond the plate's elevations by which the window
        widens (far above or below, the whole plate's average), 0..10; 0 keeps the band's.
    sides : bool
        The plate's left half fills the left, its right half the right (both straight ahead
        and behind), sharing the band's brightness; False: by elevation only.
    energy : float
        The fill's brightness, 0 (the log-average, robust to a sun in view but darker)..1 (the
        arithmetic mean's luminance, the plate's energy), between them a geometric blend.
    """

    width: float = 2.0
    saturation: float = 0.5
    spread: float = 0.5
    sides: bool = True
    energy: float = 0.5

    def __post_init__(self):
        if not (math.isfinite(self.width) and 0.5 <= self.width <= 90.0):
            raise ValueError(f"fill_width must be 0.5..90 degrees, got {self.width}")
        if not (math.isfinite(self.saturation) and 0.0 <= self.saturation <= 1.0):
            raise ValueError(f"fill_saturation must be 0..1, got {self.saturation}")
        if not (math.isfinite(self.spread) and 0.0 <= self.spread <= 10.0):
            raise ValueError(f"fill_spread must be 0..10, got {self.spread}")
        if not isinstance(self.sides, bool):
            raise ValueError(f"fill_sides must be True or False, got {self.sides!r}")
        if not (math.isfinite(self.energy) and 0.0 <= self.energy <= 1.0):
            raise ValueError(f"fill_energy must be 0..1, got {self.energy}")


@dataclass(frozen=True)
class World:
    """The world around the camera: its up and the sky prior (the artist's Surroundings).

    The sky prior is the sky taken where the plate does not show it (fill.sky_share); the
    Surroundings an artist names decide its fields (`sky_prior_for`). Vectors are in the
    camera frame.

    Parameters
    ----------
    up : (x, y, z) or None
        The world's up (the ground's normal), needed by the ground method: unseen directions
        are then filled by elevation above the world's horizon, not the camera's.
    sky_gain : float
        With `up`: how many times brighter than its level (`sky_from_plate`) the sky is taken
        to be where the
        plate does not show it, 0..MAX_SKY_GAIN; default Auto's, AUTO_SKY_GAIN
        (`sky_prior_for`; docs/ground.md).
    sky_tint : (r, g, b)
        The sky prior's colour, linear, >= 0, not black, its luminance taken out: (1, 1, 1) is
        neutral (the add-on's, but for Surroundings Custom).
    sky_from_plate : float
        What the prior's level is taken from, 0..1: 1, the whole plate's mean colour (each
        pixel clipped at 1); 0, the plate's ground in a band 5-40 degrees below the horizon
        (fill.prior_level); between, the two levels blended geometrically.
    sky_tint_share : float
        How far the prior's hue goes from grey to the plate's mean hue, 0..1.
    sky_texture : float
        With `up`: how much of the plate's own texture the unseen sky takes, 0..1 (0: the
        prior's flat colour; default methods.SKY_TEXTURE). Each sky texel is the prior times
        exp(k w (t - mean t)), t the log-luminance of the plate at the texel's direction
        folded into the plate's view, clipped to +-SKY_TEXTURE_CLIP about its mean, w fading
        from 1 at the plate's highest elevation to 0 SKY_TEXTURE_FADE_DEG above it
        (sky_texture.py): the skyline the photo shows continues around the camera as a band,
        its log-average the prior's.
    """

    up: tuple | None = None
    sky_gain: float = AUTO_SKY_GAIN
    sky_tint: tuple = (1.0, 1.0, 1.0)
    sky_from_plate: float = 1.0
    sky_tint_share: float = AUTO_SKY_TINT
    sky_texture: float = SKY_TEXTURE

    def __post_init__(self):
        if not (math.isfinite(self.sky_gain) and 0.0 <= self.sky_gain <= MAX_SKY_GAIN):
            raise ValueError(f"sky_gain must be 0..{MAX_SKY_GAIN:g}, got {self.sky_gain}")
        if not (math.isfinite(self.sky_from_plate) and 0.0 <= self.sky_from_plate <= 1.0):
            raise ValueError(f"sky_from_plate must be 0..1, got {self.sky_from_plate}")
        if not (math.isfinite(self.sky_tint_share) and 0.0 <= self.sky_tint_share <= 1.0):
            raise ValueError(f"sky_tint_share must be 0..1, got {self.sky_tint_share}")
        if not (math.isfinite(self.sky_texture) and 0.0 <= self.sky_texture <= 1.0):
            raise ValueError(f"sky_texture must be 0..1, got {self.sky_texture}")
        tint = tuple(float(v) for v in self.sky_tint)
        object.__setattr__(self, "sky_tint", tint)
        if len(tint) != 3 or not all(math.isfinite(v) and v >= 0 for v in tint) or max(tint) <= 0:
            raise ValueError(f"sky_tint must be a colour (R, G, B >= 0, not black), got {tint}")
        up = _finite("up", self.up)
        object.__setattr__(self, "up", up)
        if up is not None and (len(up) != 3 or math.hypot(*up) < 1e-9):
            raise ValueError(f"up must be a non-zero camera-frame vector, got {up}")


def _finite(name: str, value):
    """`value` as a tuple of floats (None stays None); ValueError naming `name` unless finite."""
    if value is None:
        return None
    value = tuple(float(v) for v in value)
    if not all(math.isfinite(v) for v in value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


# The parts of Params by name, and the flat keywords of one bag of fields (Params' earlier
# form, still accepted and readable): each the field of one part, the edge extension's and
# the fill's with their part's name in front ("fill_width": the fill's width).
PARTS = {"regions": Regions, "lens": Lens, "extend": Extend, "fill": Fill, "world": World}
FLAT = {
    (f"{part}_{f.name}" if part in ("extend", "fill") else f.name): (part, f.name)
    for part, kind in PARTS.items()
    for f in dataclasses.fields(kind)
}


@dataclass(frozen=True, init=False)
class Params:
    """The method and its parameters: a common part and one small part per concern.

    Which parts a method reads: "paper" the `regions` alone; "camera" (the add-on's Camera
    View) the `lens`, the edge extension (`extend`), the `fill` and the `world` (its up and
    the sky prior); "ground" those and `ground`. Every method segments the plate by
    `regions` (the add-on's advice). Frozen and validated once, part by part and then as a
    whole (ValueError naming the field). The default is the paper's method: the one that a
    plate and an object's box alone define (the others need the plate camera).

    The flat keywords of earlier versions are still accepted and readable (FLAT):
    ``Params(method="camera", hfov=60.0, fill_width=5.0)`` is ``Params(method="camera",
    lens=Lens(hfov=60.0), fill=Fill(width=5.0))``, and ``params.fill_width`` reads
    ``params.fill.width``; `dataclasses.replace` takes them too.

    Parameters
    ----------
    method : {"paper", "camera", "ground"}
        "paper" (Ropinski et al. 2004, §3.1-3.2), "camera" (camera_view.py: the plate placed
        by the camera's field of view, blurred edge extension, fill outside) or "ground" (the
        camera view plus the ground plane seen from the object: ground.py). "frustum", the
        camera method's earlier name, is stored as "camera".
    regions : Regions, optional
    lens : Lens, optional
        Needed by the camera and ground methods (`hfov` or `intrinsics`).
    extend : Extend, optional
    fill : Fill, optional
    world : World, optional
        Its `up` is needed by the ground method.
    ground : tuple of 4 to 6 floats or None
        (ox, oy, oz, height[, radius[, shadow]]) for the ground method: the object's centre in
        the camera frame (scene units), its height above the ground (> 0), the radius of the
        sphere standing for it in its contact shadow (> 0, default `height`: resting on the
        ground) and that shadow's strength (0..1, default 1: the share of the sky it hides).
    **flat
        Fields of the parts by their flat names (FLAT), applied over the parts given.
    """

    method: str = "paper"
    regions: Regions = Regions()
    lens: Lens = Lens()
    extend: Extend = Extend()
    fill: Fill = Fill()
    world: World = World()
    ground: tuple | None = None

    def __init__(
        self,
        method: str = "paper",
        regions: Regions = Regions(),
        lens: Lens = Lens(),
        extend: Extend = Extend(),
        fill: Fill = Fill(),
        world: World = World(),
        ground: tuple | None = None,
        **flat,
    ):
        parts = {"regions": regions, "lens": lens, "extend": extend, "fill": fill, "world": world}
        changes = {}
        for name, value in flat.items():
            if name not in FLAT:
                raise TypeError(f"Params() got an unexpected keyword argument {name!r}")
            part, field = FLAT[name]
            changes.setdefault(part, {})[field] = value
        for part, fields in changes.items():
            parts[part] = dataclasses.replace(parts[part], **fields)
        if isinstance(method, str) and method in METHOD_ALIASES:
            # frozen: normalised once here, so equal params hash (and cache) alike
            method = METHOD_ALIASES[method]
        object.__setattr__(self, "method", method)
        for part, value in parts.items():
            object.__setattr__(self, part, value)
        object.__setattr__(self, "ground", _finite("ground", ground))
        self._check()

    def _check(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.ground is not None and (
            len(self.ground) not in (4, 5, 6)
            or min(self.ground[3:5]) <= 0
            or not all(0.0 <= v <= 1.0 for v in self.ground[5:])
        ):
            raise ValueError(
                "ground must be (ox, oy, oz, height[, radius[, shadow]]): the object in the "
                "camera frame, its height above the ground and its radius (> 0), its contact "
                f"shadow's strength (0..1), got {self.ground}"
            )
        if reads_ground(self.method) and (self.ground is None or self.world.up is None):
            raise ValueError("the ground method needs the object's position (ground) and up")
        if uses_camera(self.method) and not self.lens.known:
            raise ValueError(
                "the camera method needs the plate camera's field of view (hfov or intrinsics)"
            )


class _Flat:
    """A flat name of Params (FLAT): on an instance its part's field, on the class its default."""

    def __init__(self, part: str, field: str):
        self.part, self.field = part, field

    def __get__(self, params, owner=None):
        if params is None:
            return getattr(PARTS[self.part], self.field)
        return getattr(getattr(params, self.part), self.field)


for _name, (_part, _field) in FLAT.items():
    setattr(Params, _name, _Flat(_part, _field))
