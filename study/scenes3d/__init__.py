"""A 3D ground truth (issue 11, item 1): scenes path-traced in Cycles with the `bpy` module, the
plate rendered without the subject, the truth with it (a mirror and a rough glossy at two
roughnesses), and every method's render of the subject alone composited over the plate.

- `scenes`: the scene descriptions, drawn from seeds (no bpy);
- `build`: a description as a Blender scene, and the baselines' worlds (bpy);
- `run`: renders, Generate per add-on method, scores on the subject's pixels (bpy);
- `report`: summaries, the tables of docs/scenes3d.md, the charts (no bpy).

`python -m study scenes [--quick] [--cases failures|inter|motion] [--out DIR] [--jobs 1]` runs
it (`run_command`); `--mirror-only [--cache DIR]` only the mirror subject with the default
method and the plate mean, the plate and truth renders cached (`mirror`: a fast loop);
`--cases failures` runs the failure cases instead (issue 11, item 5),
`--cases inter` the inter-reflection cases (`inter`: one pass against the paper's passes,
issue 11, item 4), `--cases motion` the sequences of a moving subject and camera (`motion`,
`motion_run`, `motion_report`), `--cases heldout` the scenes under the held-out HDRIs,
`--cases more --mirror-only` 32 scenes more drawn as the default 16 are, `--cases polyhaven`
30 scenes under 15 Poly Haven HDRIs that are none of Blender's (`study/polyhaven.py`), and
`--cases all --mirror-only` the last four in turn and the mirror target over them
(`pooled`). Research only: bpy is imported when a run starts (once per process); the product
never imports this.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
import os
import pathlib
import platform
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass

from . import scenes

COMMAND = "python -m study scenes"


class ScenesInputError(Exception):
    """Bad input to the command (bpy missing, unwritable folder); one line."""


CASES = ("default", "failures", "inter", "motion", "heldout", "more", "polyhaven", "all")
SURROUNDINGS = (
    "auto",
    "open",
    "enclosed",
    "world",
    "artist",
)  # --surroundings (run.surroundings_of)
ORACLES = ("shadow", "proxies")  # --oracle (oracles.py)


@dataclass(frozen=True)
class Config:
    quick: bool = False
    width: int = 320  # x 180
    samples: int = 32
    cases: str = "default"  # "failures": scenes.failure_set, with the ground-chosen row;
    # "inter": scenes.inter_set, one pass against the passes (inter.py)

    def specs(self):
        if self.cases == "failures":
            return scenes.failure_set(self.quick)
        if self.cases == "inter":
            return scenes.inter_set(self.quick)
        if self.cases == "heldout":
            return scenes.held_out_set(self.quick)
        if self.cases == "more":
            return scenes.more_set(self.quick)
        if self.cases == "polyhaven":
            return scenes.polyhaven_set(self.quick)
        return scenes.scene_set(self.quick)

    @property
    def name(self) -> str:
        """The outputs' stem: scenes3d, scenes3d_quick, scenes3d_failures(_quick),
        scenes3d_inter(_quick)."""
        return (
            "scenes3d"
            + ("" if self.cases == "default" else f"_{self.cases}")
            + ("_quick" if self.quick else "")
        )


FULL = Config()
QUICK = Config(quick=True, width=256, samples=16)
FAILURES = Config(cases="failures")
QUICK_FAILURES = Config(quick=True, width=160, samples=8, cases="failures")
INTER = Config(cases="inter")
QUICK_INTER = Config(quick=True, width=192, samples=16, cases="inter")
CONFIGS = {  # (cases, quick) -> Config
    ("default", False): FULL,
    ("default", True): QUICK,
    ("failures", False): FAILURES,
    ("failures", True): QUICK_FAILURES,
    ("inter", False): INTER,
    ("inter", True): QUICK_INTER,
    ("heldout", False): Config(cases="heldout"),
    ("heldout", True): Config(quick=True, width=256, samples=16, cases="heldout"),
    ("more", False): Config(cases="more"),
    ("more", True): Config(quick=True, width=256, samples=16, cases="more"),
    ("polyhaven", False): Config(cases="polyhaven"),
    ("polyhaven", True): Config(quick=True, width=256, samples=16, cases="polyhaven"),
}
HELD_OUT_CASES = {"heldout": "Held-out HDRIs", "polyhaven": "Poly Haven HDRIs"}  # doc blocks


def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def default_cache() -> pathlib.Path:
    """Where `--mirror-only` keeps its plate, truth and plate-mean renders by default."""
    return pathlib.Path(tempfile.gettempdir()) / "vr_scenes3d_mirror_cache"


def run_mirror(
    config: Config,
    cache=None,
    log=None,
    sky_gain=None,
    split=False,
    surroundings=None,
    oracle=None,
    contact_shadow=None,
):
    """The fast mirror loop (mirror.py) over ``config``'s scenes: returns the JSON record
    (as `run_study`'s, with the mirror only, the default method and the plate mean).
    ``sky_gain``: the default method's maps built with that Params.sky_gain (None: as is);
    ``split``: each scene's error split (`mirror.error_split`: one more render a scene);
    ``surroundings``: the panel's Surroundings in every scene (auto, open, enclosed, world:
    the scene's dome read from its world), or "artist": each scene's by the kind of its HDRI
    (`run.surroundings_of`); ``oracle``: each scene's rows of that oracle (`oracles`);
    ``contact_shadow``: the panel's Contact Shadow in every scene (None: the add-on's)."""
    try:
        from . import mirror
    except ImportError as exc:
        raise ScenesInputError(f"the 3D study needs the bpy module: {exc}") from exc
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    cache = pathlib.Path(cache) if cache else default_cache()
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ScenesInputError(f"cannot write in {cache}: {exc.strerror}") from exc
    work = pathlib.Path(tempfile.mkdtemp(prefix="vr_scenes3d_mirror_"))
    started = time.perf_counter()
    try:
        records, _, methods = mirror.run_scenes(
            config.specs(),
            cache,
            work,
            config.width,
            config.samples,
            say,
            sky_gain,
            split,
            surroundings,
            oracle,
            contact_shadow,
        )
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return {
        "command": COMMAND
        + (" --quick" if config.quick else "")
        + ("" if config.cases == "default" else f" --cases {config.cases}")
        + " --mirror-only"
        + ("" if sky_gain is None else f" --sky-gain {sky_gain:g}")
        + ("" if surroundings is None else f" --surroundings {surroundings}")
        + (" --split" if split else "")
        + ("" if oracle is None else f" --oracle {oracle}")
        + ("" if contact_shadow is None else f" --contact-shadow {contact_shadow:g}")
        + (
            ""
            if config == CONFIGS[config.cases, config.quick]
            else f" --width {config.width} --samples {config.samples}"
        ),
        "sky_gain": sky_gain,
        "oracle": oracle,
        "surroundings": surroundings,
        "contact_shadow": contact_shadow,
        "quick": config.quick,
        "mirror_only": True,
        "resolution": [config.width, round(config.width / scenes.ASPECT)],
        "samples": config.samples,
        "addon_methods": methods,
        "baselines": [mirror.run.MEAN],
        "scenes": records,
        "machine": _machine(),
        "seconds": time.perf_counter() - started,
    }


def _machine() -> dict:
    """What the figures were measured on (bpy is importable once a run has rendered)."""
    import bpy

    return {
        "bpy": bpy.app.version_string,
        "python": platform.python_version(),
        "cores": os.cpu_count(),
    }


def run_study(config: Config, log=None, keep=None):
    """Render and score every scene of ``config``. Returns (data, crops): ``data`` the JSON
    record (``scenes``, ``addon_methods``, ``baselines``, settings, machine, seconds),
    ``crops`` {scene: {column: display crop}} for the contact sheet. ``keep``: a folder to keep
    the renders in (default: a temporary one, removed)."""
    try:
        from . import inter, run
    except ImportError as exc:  # bpy (or Blender's own modules) not importable
        raise ScenesInputError(f"the 3D study needs the bpy module: {exc}") from exc
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    specs = config.specs()
    work = pathlib.Path(keep) if keep else pathlib.Path(tempfile.mkdtemp(prefix="vr_scenes3d_"))
    started = time.perf_counter()
    try:
        if config.cases == "inter":
            records, crops, methods = inter.run_scenes(
                specs, work, config.width, config.samples, say
            )
        else:
            records, crops, methods = run.run_scenes(
                specs,
                work,
                config.width,
                config.samples,
                say,
                config.cases == "failures",
                # the artist's Surroundings as a row of its own: the full sets only
                config.cases in ("default", *HELD_OUT_CASES) and not config.quick,
            )
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    failures = config.cases == "failures"
    data = {
        "command": COMMAND
        + (" --quick" if config.quick else "")
        + ("" if config.cases == "default" else f" --cases {config.cases}"),
        "quick": config.quick,
        "resolution": [config.width, round(config.width / scenes.ASPECT)],
        "samples": config.samples,
        "denoised": run.build.build_scenes().has_oidn(),
        "hdris": sorted({spec.hdri for spec in specs}),
        "held_out_hdris": list(scenes.HELD_OUT),
        "materials": [{"name": n, "roughness": r, "combine": c} for n, r, c in run.MATERIALS],
        "addon_methods": methods,
        "baselines": list(run.BASELINES),
        "metrics": list(run.METRICS),
        "scenes": records,
        "machine": _machine(),
        "seconds": time.perf_counter() - started,
    }
    if config.cases in HELD_OUT_CASES:
        data["cases"] = config.cases
    if config.cases == "inter":
        data["cases"] = "inter"
        data["materials"] = [{"name": "mirror", "roughness": 0.0, "combine": "REPLACE"}]
        data["baselines"] = [run.MEAN]
        data["glossy_bounces"] = inter.GLOSSY_BOUNCES
        data["default_method"] = methods[0]  # inter.run_scenes puts it first
    if failures:
        data["cases"] = "failures"
        data["default_method"] = (
            methods[0]
            if run.GROUND_CHOSEN not in methods
            else (methods[methods.index(run.GROUND_CHOSEN) - 1])
        )
    return data, crops


def run_command(
    quick=False,
    out=None,
    jobs=1,
    log=None,
    cases="default",
    mirror_only=False,
    cache=None,
    sky_gain=None,
    split=False,
    surroundings=None,
    oracle=None,
    contact_shadow=None,
    width=None,
    samples=None,
    sheet=None,
):
    """The `scenes` sub-command: run, print the means, and with ``out`` (default docs for the
    full set; nothing for --quick unless given) write OUT/scenes3d.json (scenes3d_quick.json),
    the tables of OUT/scenes3d.md and OUT/images/scenes3d_{pareto,examples}.png. With
    ``cases="failures"``: the failure cases, written to OUT/scenes3d_failures.json, the
    "Where it fails" table of OUT/scenes3d.md and OUT/images/scenes3d_failures_*.png.
    ``mirror_only``: the fast mirror loop (`run_mirror`, renders cached in ``cache``, the sky
    prior's gain ``sky_gain`` or the panel's ``surroundings`` if given): prints its table,
    and with ``out`` writes only OUT/scenes3d_mirror(_quick).json; with ``split`` also where
    the default's error lies (`mirror.split_table`), how its level statistic and the
    constant gain score (`prior_level.statistic_table`) and its colour
    (`prior_colour.colour_table`); with ``oracle`` also that oracle's rows
    (`oracles`, `mirror.oracle_table`); ``contact_shadow``: the panel's Contact Shadow in every
    scene; ``width`` and ``samples``: its renders' width (the
    height 9/16 of it) and Cycles samples in place of the set's. ``sheet``: only the mirror
    sheet (`run_sheet`), written to that PNG (with ``cache``, ``width`` and ``samples``)."""
    if sheet is not None:
        return run_sheet(sheet, cache=cache, width=width, samples=samples, log=log), {}
    options = dict(
        cache=cache,
        sky_gain=sky_gain,
        split=split,
        surroundings=surroundings,
        oracle=oracle,
        contact_shadow=contact_shadow,
    )
    _check_options(jobs, cases, mirror_only, width=width, samples=samples, **options)
    if cases == "all":
        return run_all(quick, out, log, mirror_only, width=width, samples=samples, **options)
    if cases == "motion":  # the sequences (motion.py): their own outputs
        from . import motion_report

        try:
            return motion_report.run_command(quick=quick, out=out, log=log), {}
        except motion_report.MotionInputError as exc:
            raise ScenesInputError(str(exc)) from exc
    config = _config(cases, quick, mirror_only, width, samples, log)
    if mirror_only:
        return _mirror_command(config, out, log, **options)
    return _study_command(config, quick, out, log)


def _check_options(
    jobs,
    cases,
    mirror_only,
    *,
    cache,
    sky_gain,
    split,
    surroundings,
    oracle,
    contact_shadow,
    width,
    samples,
) -> None:
    """Raise `ScenesInputError` for an option out of its range, one that goes only with
    --mirror-only, or --sky-gain with --surroundings."""
    if not mirror_only and (
        cache is not None
        or sky_gain is not None
        or split
        or surroundings is not None
        or oracle is not None
        or contact_shadow is not None
        or width is not None
        or samples is not None
    ):
        raise ScenesInputError(
            "--cache, --sky-gain, --surroundings, --split, --oracle, --contact-shadow, --width and "
            "--samples go with --mirror-only"
        )
    if width is not None and not 64 <= width <= 3840:
        raise ScenesInputError(f"--width: 64..3840, not {width}")
    if samples is not None and not 1 <= samples <= 4096:
        raise ScenesInputError(f"--samples: 1..4096, not {samples}")
    if oracle not in (None, *ORACLES):
        raise ScenesInputError(f"--oracle: one of {', '.join(ORACLES)}, not {oracle!r}")
    if sky_gain is not None and surroundings is not None:
        raise ScenesInputError("--sky-gain or --surroundings, not both")
    if surroundings not in (None, *SURROUNDINGS):
        raise ScenesInputError(
            f"--surroundings: one of {', '.join(SURROUNDINGS)}, not {surroundings!r}"
        )
    if sky_gain is not None and not (math.isfinite(sky_gain) and 0.0 <= sky_gain <= 100.0):
        raise ScenesInputError(f"--sky-gain: 0..100, not {sky_gain}")
    if contact_shadow is not None and not (
        math.isfinite(contact_shadow) and 0.0 <= contact_shadow <= 1.0
    ):
        raise ScenesInputError(f"--contact-shadow: 0..1, not {contact_shadow}")
    if jobs != 1:
        raise ScenesInputError(
            "--jobs: only 1 is supported (one bpy per process; Cycles already uses every core)"
        )
    if cases not in CASES:
        raise ScenesInputError(f"--cases: one of {', '.join(CASES)}, not {cases!r}")


def _config(cases, quick, mirror_only, width, samples, log) -> Config:
    """The set's `Config` at ``width`` and ``samples`` if given; the Poly Haven HDRIs fetched
    for their set; `ScenesInputError` for a set that does not go with ``mirror_only``."""
    config = CONFIGS[cases, bool(quick)]
    if width is not None or samples is not None:
        config = dataclasses.replace(
            config, width=width or config.width, samples=samples or config.samples
        )
    if cases == "more" and not mirror_only:
        raise ScenesInputError("--cases more runs with --mirror-only only")
    if cases == "polyhaven":
        from .. import polyhaven

        try:
            polyhaven.ensure(log=log or (lambda line: print(line, file=sys.stderr, flush=True)))
        except polyhaven.PolyHavenError as exc:
            raise ScenesInputError(str(exc)) from exc
    if mirror_only and cases not in ("default", "heldout", "more", "polyhaven"):
        raise ScenesInputError(
            "--mirror-only runs the default, the held-out, the more or the Poly Haven scenes only"
        )
    return config


def _mirror_command(config, out, log, **options):
    """`run_command` with --mirror-only: the fast mirror loop (`run_mirror` with ``options``),
    its tables printed and, with ``out``, OUT/scenes3d_mirror(_quick).json written."""
    split, oracle = options["split"], options["oracle"]
    data = run_mirror(config, log=log, **options)
    from . import mirror, prior_colour, prior_level  # bpy is importable: run_mirror said so

    print(mirror.table(data))
    if split:
        print()
        print(mirror.split_table(data))
        print()
        print(prior_level.statistic_table(data))
        print(prior_level.scene_gains_line(data))
        print()
        print(prior_colour.colour_table(data))
    if oracle is not None:
        print()
        print(mirror.oracle_table(data, oracle))
    print(f"{len(data['scenes'])} scenes in {data['seconds']:.0f} s")
    if out:
        target = pathlib.Path(out)
        target.mkdir(parents=True, exist_ok=True)
        path = target / (config.name.replace("scenes3d", "scenes3d_mirror") + ".json")
        path.write_text(json.dumps(_json_safe(data), indent=1) + "\n")
        print(f"wrote {path}", file=sys.stderr)
    return data, {}


def _study_command(config, quick, out, log):
    """`run_command` for every method: the study run, its table printed and, into ``out``
    (default docs for the full set; nothing for --quick unless given), its outputs written."""
    target = pathlib.Path(out) if out else (None if quick else pathlib.Path("docs"))
    if target is not None:
        try:
            (target / "images").mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ScenesInputError(f"cannot write in {target}: {exc.strerror}") from exc
    data, crops = run_study(config, log=log)
    from . import report

    table = {"failures": report.table_failures, "inter": report.table_inter}
    print(table.get(config.cases, report.table_means)(data))
    print(
        f"{len(data['scenes'])} scenes in {data['seconds']:.0f} s on {data['machine']['cores']} "
        f"cores (bpy {data['machine']['bpy']})"
    )
    if target is not None:
        write_outputs(data, crops, target, config.name)
    return data, crops


def run_sheet(path, cache=None, width=None, samples=None, log=None) -> list:
    """`--sheet PNG`: the mirror sheet of sheet.py (a dozen held-out and Poly Haven scenes:
    truth, default, on-set probe, plate mean), renders cached in ``cache`` (default: the
    mirror loop's), at ``width`` x 9/16 and ``samples`` (default: the study's, 320 and 32).
    Prints each scene and the time; returns the records."""
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    path = pathlib.Path(path)
    if path.suffix.lower() != ".png":
        raise ScenesInputError(f"--sheet: a .png path, not {str(path)!r}")
    width, samples = width or FULL.width, samples or FULL.samples
    if not 64 <= width <= 3840:
        raise ScenesInputError(f"--width: 64..3840, not {width}")
    if not 1 <= samples <= 4096:
        raise ScenesInputError(f"--samples: 1..4096, not {samples}")
    cache = pathlib.Path(cache) if cache else default_cache()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        cache.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ScenesInputError(f"cannot write in {exc.filename}: {exc.strerror}") from exc
    from .. import polyhaven

    try:
        polyhaven.ensure(log=say)
    except polyhaven.PolyHavenError as exc:
        raise ScenesInputError(str(exc)) from exc
    try:
        from . import sheet
    except ImportError as exc:
        raise ScenesInputError(f"the 3D study needs the bpy module: {exc}") from exc
    work = pathlib.Path(tempfile.mkdtemp(prefix="vr_scenes3d_sheet_"))
    started = time.perf_counter()
    try:
        records = sheet.write(path, cache, work, width, samples, say)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(sheet.means_line(records))
    print(
        f"wrote {path}: {len(records)} scenes at {width} px, {samples} samples in "
        f"{time.perf_counter() - started:.0f} s"
    )
    return records


def run_all(quick, out, log, mirror_only, **options):
    """`--cases all --mirror-only`: each set of `pooled.SETS` in turn through the fast mirror
    loop with ``options`` (`run_command`'s; its table printed as its own run prints it), then
    `pooled.pooled_table`; with ``out`` OUT/scenes3d_mirror_all(_quick).json holds the four
    records."""
    from . import pooled

    if not mirror_only:
        raise ScenesInputError("--cases all runs with --mirror-only only")
    runs = {}
    for name in pooled.SETS:
        print(f"\n## {pooled.TITLES[name]}\n")
        runs[name], _ = run_command(
            quick=quick,
            log=log,
            cases=name,
            mirror_only=True,
            **options,
        )
    print("\n## The mirror over every set\n")
    print(pooled.pooled_table(runs))
    if out:
        target = pathlib.Path(out)
        target.mkdir(parents=True, exist_ok=True)
        path = target / ("scenes3d_mirror_all" + ("_quick" if quick else "") + ".json")
        path.write_text(json.dumps(_json_safe({"sets": runs}), indent=1) + "\n")
        print(f"wrote {path}", file=sys.stderr)
    return runs, {}


def write_outputs(data, crops, target, name=None) -> None:
    from . import report

    target = pathlib.Path(target)
    (target / "images").mkdir(parents=True, exist_ok=True)
    name = name or ("scenes3d_quick" if data["quick"] else "scenes3d")
    if data.get("cases") == "failures":
        write_failures(data, crops, target, name)
        return
    if data.get("cases") == "inter":
        write_inter(data, crops, target, name)
        return
    if data.get("cases") in HELD_OUT_CASES:
        write_heldout(data, target, name)
        return
    (target / f"{name}.json").write_text(json.dumps(_json_safe(data), indent=1) + "\n")
    if importlib.util.find_spec("matplotlib") is None:
        print("matplotlib is not installed: no charts", file=sys.stderr)
    else:
        report.chart_pareto(data, target / "images" / f"{name}_pareto.png")
        report.contact_sheet(data, crops, target / "images" / f"{name}_examples.png")
    header = (
        "# The 3D ground truth\n\n"
        f"Generated by `{data['command']}`; the tables between the markers are rewritten by "
        "it.\n"
    )
    report.update_markdown(target / f"{name}.md", report.blocks(data), header)
    print(
        f"wrote {target / (name + '.json')}, {target / (name + '.md')} and the charts in "
        f"{target / 'images'}",
        file=sys.stderr,
    )


def write_failures(data, crops, target, name) -> None:
    """OUT/NAME.json, the contact sheet of every case, and the "Where it fails" block of
    OUT/scenes3d(_quick).md (appended under its heading when the file lacks it)."""
    from . import report

    (target / f"{name}.json").write_text(json.dumps(_json_safe(data), indent=1) + "\n")
    if importlib.util.find_spec("matplotlib") is None:
        print("matplotlib is not installed: no charts", file=sys.stderr)
    else:
        report.contact_sheet(
            data, crops, target / "images" / f"{name}_examples.png", names=list(crops)
        )
        report.chart_failures(data, target / "images" / f"{name}.png")
    md = target / ("scenes3d_quick.md" if data["quick"] else "scenes3d.md")
    report.add_failures_block(md, report.table_failures(data), data["command"])
    print(
        f"wrote {target / (name + '.json')}, {md} and the charts in {target / 'images'}",
        file=sys.stderr,
    )


def write_heldout(data, target, name) -> None:
    """OUT/NAME.json and the "heldout" (or "polyhaven") block of OUT/scenes3d(_quick).md (the
    means and the mirror per scene; appended under its heading when the file lacks it)."""
    from . import report

    (target / f"{name}.json").write_text(json.dumps(_json_safe(data), indent=1) + "\n")
    md = target / ("scenes3d_quick.md" if data["quick"] else "scenes3d.md")
    table = report.table_means(data) + "\n\n" + report.table_scenes(data)
    cases = data["cases"]
    report.add_block(md, cases, HELD_OUT_CASES[cases], table, data["command"])
    print(f"wrote {target / (name + '.json')} and {md}", file=sys.stderr)


def write_inter(data, crops, target, name) -> None:
    """OUT/NAME.json, the contact sheet (truth, one pass and auto per method) and the
    "Inter-reflections" and "traced" blocks of OUT/scenes3d(_quick).md (appended when
    missing)."""
    from . import report

    (target / f"{name}.json").write_text(json.dumps(_json_safe(data), indent=1) + "\n")
    if importlib.util.find_spec("matplotlib") is None:
        print("matplotlib is not installed: no charts", file=sys.stderr)
    else:
        report.contact_sheet_inter(data, crops, target / "images" / f"{name}_examples.png")
    md = target / ("scenes3d_quick.md" if data["quick"] else "scenes3d.md")
    report.add_block(md, "inter", "Inter-reflections", report.table_inter(data), data["command"])
    traced = report.table_traced(data)
    if traced:
        report.add_block(
            md, "traced", "The ray-traced pass: seeing against blind", traced, data["command"]
        )
    print(
        f"wrote {target / (name + '.json')}, {md} and the charts in {target / 'images'}",
        file=sys.stderr,
    )
