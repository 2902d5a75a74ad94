"""The choices an artist makes, each list defined once: the methods, the Surroundings, the looks.

The panel's enum items (operators/scene/choices.py), both command lines' ``choices``
(render_shot.py, cli.py), the batch's options (operators/batch/options.py) and `Params`
take them from here, and the add-on asks the predicates below what a method does instead of
comparing its name. A
method or a Surroundings is named in lower case ("ground"), the name the engine and the
command lines use; the panel stores its upper-case key ("GROUND"), and every function here
takes either. The looks (combine modes) are the add-on's, not the engine's; they are listed
here because render_shot.py parses its command line before Blender's modules load.

No NumPy and nothing of the engine: every other module may import this one.
"""

from __future__ import annotations

from dataclasses import dataclass

MAX_TRIANGLES = 1024  # the paper's front face: at most this many triangles (a multiple of 4)


@dataclass(frozen=True)
class Choice:
    """One item of a choice list.

    Attributes
    ----------
    name : str
        The engine's and the command lines' name ("ground"; a look: "REPLACE").
    label : str
        The panel's name for it.
    description : str
        The panel's tooltip.
    """

    name: str
    label: str
    description: str

    @property
    def key(self) -> str:
        """The panel's enum identifier, stored in .blend files: the name in upper case."""
        return self.name.upper()


@dataclass(frozen=True)
class Method(Choice):
    """A method: how the plate becomes an object's environment map.

    Attributes
    ----------
    camera : bool
        Places the plate by the camera's field of view (needs a perspective camera, or the
        engine's hfov/intrinsics); without one the paper's method stands in.
    ground : bool
        Reads the ground under the object: needs the object's place in the scene, so not a
        method for a plate and a box alone (the engine's command line).
    distant : bool
        Takes everything around as distant: neighbouring objects show little of each other.
    """

    camera: bool = False
    ground: bool = False
    distant: bool = False


# The panel lists them in this order (a .blend stores an enum by its index: add at the end).
METHODS = (
    Method(
        "ground",
        "Camera View + Ground",
        "Camera View, and the ground the objects stand on seen from each object: what a mirror "
        "shows below it comes from where the photo shows that ground (the ground: the Ground "
        "object, else a shadow catcher, else the objects' lowest point; docs/ground.md)",
        camera=True,
        ground=True,
    ),
    Method(
        "camera",
        "Camera View",
        "Place the plate exactly by the camera's field of view, everything taken as distant; "
        "where the photo saw nothing, extend its edges into the sky, ground and sides it "
        "suggests (docs/accuracy.md)",
        camera=True,
        distant=True,
    ),
    Method(
        "paper",
        "Paper (2004)",
        "Ropinski et al.: the plate cut into regions around the object's bounds and folded "
        "onto a cube (neighbouring objects show on the sides facing them)",
    ),
)
METHOD_NAMES = tuple(m.name for m in METHODS)
# The methods a plate and the object's box on it are enough for (the engine's command line).
PLATE_METHODS = tuple(m.name for m in METHODS if not m.ground)
METHOD_ALIASES = {"frustum": "camera"}  # earlier name of the camera-view method, still accepted

# The sky prior's gain (Params.sky_gain) for the surroundings an artist can name: "auto" knows
# nothing of the shot (the gain that best predicts the upper hemisphere of six of Blender's
# HDRIs from their lower one), "open" is outdoors under open sky (the same fit on city, sunrise
# and sunset), "enclosed" a room, a studio or a walled yard (courtyard, interior, studio).
# `python -m study sky-prior` derives all three; tests/study/test_sky_prior.py ties them to it.
SKY_GAINS = {"auto": 1.6, "open": 3.6, "enclosed": 0.7}

# Auto's unseen sky is the photo's own mean colour (each pixel clipped at display white, so a
# sun or a lamp in an HDR plate counts as white): AUTO_SKY_GAIN times as bright, its hue
# AUTO_SKY_TINT of the way from grey to the photo's. The ground-band gain above guessed the
# sky from the ground near the horizon and was fitted on six of Blender's HDRIs; on HDRIs it
# had not seen it lost up to 2 dB to a flat world of the plate's mean colour. These two were
# fitted leave-one-HDRI-out on 50 scenes under 23 HDRIs (the most mean PSNR whose worst scene
# stays within 1 dB of that flat world): `python -m study.scenes3d.heldout_sky fit OUT --auto`.
AUTO_SKY_GAIN = 1.4
AUTO_SKY_TINT = 0.75
# The unseen sky takes the photo's own texture (Params.sky_texture, the panel's Sky Texture;
# sky_texture.py): SKY_TEXTURE of the plate's log-contrast, in a band that fades out
# sky_texture.SKY_TEXTURE_FADE_DEG above the plate's highest elevation. Both chosen
# leave-one-HDRI-out on the same 50 scenes, rendered by Generate: on the other HDRIs' scenes,
# of the settings that meet issue 41's bars (worst scene within 1 dB of the plate-mean world,
# mean +1.0 dB, 75 % ahead, SSIM +0.10, FLIP 0.48), the one with the most upper-half detail:
# `python -m study.scenes3d.sky_texture_addon render OUT`, then `score OUT`.
SKY_TEXTURE = 0.75
# A rough surface's map (the Mix look's pre-filtered map, the World look's light) takes the
# ground band's brighter sky, ROUGH_SKY_RATIOS' (fitted with it): Auto blends from the plate's
# colour at roughness 0 to that sky at AUTO_SKY_ROUGHNESS, the first rough knot, and beyond.
AUTO_SKY_ROUGHNESS = 0.15

# Surroundings: how bright the sky the plate does not show is taken to be (Camera View +
# Ground). The first three are SKY_GAINS'; "world" reads the shot's world HDRI, "custom" the
# artist's Sky Brightness. Last: a file stores an enum by its index, so a new one goes after.
SURROUNDINGS = (
    Choice(
        "auto",
        "Auto",
        "Nothing said of the shot: the sky the photo does not show takes the photo's own "
        f"mean colour, {AUTO_SKY_GAIN:g} times as bright (learnt from HDRIs of every kind, "
        "held out one at a time; never far from a flat world of that colour)",
    ),
    Choice(
        "open",
        "Open Sky",
        "Outdoors, the sky over most of what stands around (streets, fields, a sunset): the "
        f"unseen sky is taken brighter, {SKY_GAINS['open']:g} times the ground's",
    ),
    Choice(
        "enclosed",
        "Enclosed",
        "A dim room, a studio or a yard walled in by buildings: what is above and behind the "
        f"camera is taken darker, {SKY_GAINS['enclosed']:g} times the ground's brightness (for a "
        "mirror; in the Glossy look a rough surface's map takes a brighter sky, by roughness). "
        "A brightly lit hall, lobby or workshop is closer to Auto",
    ),
    Choice(
        "world",
        "World HDRI",
        "The scene's world holds the HDRI shot on set: what the photo does not show comes "
        "from it, turned and as bright as the world is set (read, never changed)",
    ),
    Choice(
        "custom",
        "Custom",
        "Say how bright the unseen sky is: Sky Brightness times the ground's brightness in the "
        f"photo (an average place is near {SKY_GAINS['auto']:g}; a rough surface's map takes a "
        "brighter sky by roughness, as under Auto)",
    ),
)
SURROUNDINGS_NAMES = tuple(s.name for s in SURROUNDINGS)


@dataclass(frozen=True)
class Look(Choice):
    """A look (Combine): how a map meets each object's material.

    Attributes
    ----------
    whole_surface : bool
        The map is the whole surface, an emission (Replace, Modulate): a mirror of its colour.
    shared : bool
        One map shared by every object as world lighting (World), not a map per object.
    """

    whole_surface: bool = False
    shared: bool = False


# The looks, named in upper case everywhere.
COMBINES = (
    Look(
        "REPLACE",
        "Replace",
        "Chrome: the object shows the environment map (the paper's replace mode)",
        whole_surface=True,
    ),
    Look(
        "MODULATE",
        "Modulate",
        "Material colour times the environment (the paper's modulate mode)",
        whole_surface=True,
    ),
    Look("MIX", "Mix", "Blend the map over the material's own shader by strength and Fresnel"),
    Look(
        "WORLD",
        "World",
        "Use one shared map as camera-aligned world lighting for any material",
        shared=True,
    ),
)
COMBINE_NAMES = tuple(c.name for c in COMBINES)
WHOLE_SURFACE_LOOKS = tuple(c.name for c in COMBINES if c.whole_surface)
PER_OBJECT_LOOKS = tuple(c.name for c in COMBINES if not c.shared)  # a map for each object


def method(key: str) -> Method:
    """The method of a name or a panel key.

    Parameters
    ----------
    key : str
        "ground", "GROUND", an alias of METHOD_ALIASES; KeyError for another.

    Returns
    -------
    Method
    """
    name = str(key).lower()
    name = METHOD_ALIASES.get(name, name)
    for m in METHODS:
        if m.name == name:
            return m
    raise KeyError(key)


def uses_camera(key: str) -> bool:
    """Whether the method places the plate by the camera's view (Camera View, + Ground)."""
    return method(key).camera


def reads_ground(key: str) -> bool:
    """Whether the method reads the ground under the objects (Camera View + Ground)."""
    return method(key).ground


def cuts_regions(key: str) -> bool:
    """Whether the method cuts the plate into the paper's regions (Paper)."""
    return not method(key).camera


def takes_all_distant(key: str) -> bool:
    """Whether the method takes all around as distant, neighbours included (Camera View)."""
    return method(key).distant


def view_method(key: str, perspective: bool) -> str:
    """The engine's method (Params.method) a view of the plate takes before any ground.

    Parameters
    ----------
    key : str
        The artist's method (a name or a panel key).
    perspective : bool
        Whether the camera is a perspective one (its intrinsics are known).

    Returns
    -------
    str
        "camera" for a method placed by the camera's view under a perspective camera, else
        "paper"; the ground is added per map where it applies.
    """
    return "camera" if perspective and uses_camera(key) else "paper"


def takes_world_hdri(key: str, surroundings: str) -> bool:
    """Whether the unseen surroundings come from the scene's world HDRI: a method reading the
    ground with Surroundings World HDRI."""
    return reads_ground(key) and str(surroundings).lower() == "world"
