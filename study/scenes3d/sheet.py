"""The mirror sheet (issue 41, item 7; `python -m study scenes --sheet PNG`): a dozen scenes
under HDRIs the add-on was not fitted on, one row each: the truth, the add-on's default
(Camera View + Ground, Auto), the on-set probe and the plate mean, cropped around the mirror
subject, each with its PSNR and FLIP (report.sheet_figure).

The scenes: six of the held-out set (`scenes.held_out_set`, the HDRIs forest and night,
nothing was tuned on them) and six of the Poly Haven set (`scenes.polyhaven_set`: none of
Blender's HDRIs, but later choices, the Surroundings kinds and their gains, were made looking
at it). Renders through the fast mirror loop (mirror.run_scene, with the probe), so the plate,
truth, plate-mean and probe renders are cached (``cache``) and a re-run renders only the
add-on's.

Research only (bpy); run through `study.scenes3d.run_sheet`.
"""

from __future__ import annotations

import pathlib

import numpy as np

from . import mirror, report, run, scenes

HELD_OUT = ("s201", "s202", "s203", "s204", "s205", "s206")  # sphere, torus, Suzanne x 2 HDRIs
POLYHAVEN = ("s327", "s313", "s302", "s303", "s311", "s310")  # sky, sunset, bridge, city, park,
# night: an open sky with a sun to a dark street
SETS = {"held out": HELD_OUT, "Poly Haven": POLYHAVEN}


def specs() -> list:
    """[(Scene3D, set label)] in the sheet's order: the held-out scenes, then Poly Haven's."""
    drawn = {s.name.split("_")[0]: s for s in scenes.held_out_set() + scenes.polyhaven_set()}
    return [(drawn[key], tag) for tag, keys in SETS.items() for key in keys]


def render_rows(cache, work, width, samples, log) -> tuple:
    """Each scene of `specs` through the mirror loop with the probe: (rows for
    report.sheet_figure, the default method's label, the records)."""
    addon = run.Addon()
    rows, records = [], []
    try:
        label = run.default_method_label(addon)
        for spec, tag in specs():
            record, crops = mirror.run_scene(
                spec,
                addon,
                pathlib.Path(cache),
                pathlib.Path(work),
                width,
                samples,
                log,
                probe=True,
            )
            records.append(record)
            rows.append((spec.name, tag, crops, record["results"][mirror.MIRROR]))
    finally:
        run.new_file()
        addon.close()
    return rows, label, records


def write(path, cache, work, width, samples, log) -> list:
    """Render (or read from ``cache``) and write the sheet to ``path``; returns the records."""
    rows, label, records = render_rows(cache, work, width, samples, log)
    report.write_sheet(rows, label, path)
    return records


def means_line(records) -> str:
    """One line: each column's mean mirror PSNR and FLIP over the sheet's scenes, per set."""
    parts = []
    for tag, keys in SETS.items():
        rows = [r["results"][mirror.MIRROR] for r in records if r["scene"]["name"][:4] in keys]
        if not rows:
            continue
        cells = ", ".join(
            f"{name} {np.mean([r[name]['psnr'] for r in rows]):.2f} dB / FLIP "
            f"{np.mean([r[name]['flip'] for r in rows]):.3f}"
            for name in rows[0]
            if name != "(plate itself)"
        )
        parts.append(f"{tag} ({len(rows)}): {cells}")
    return "means: " + "; ".join(parts)
