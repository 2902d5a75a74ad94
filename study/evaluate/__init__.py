"""Accuracy against ground truth (issue 5): how close each method's map comes to the real
surroundings of a plate, and at what cost.

- `study`: ground truth from Blender's bundled HDRIs (plates, true lat-long maps), the cases,
  the run, summaries, the issue's targets and the claims docs/accuracy.md makes;
- `spheres`: mirror, matte-silver and diffuse probe spheres rendered from a lat-long map;
- `metrics`: si-RMSE, RGB angular error, PSNR, SSIM, and the plate's own view of a map;
- `baselines`: the methods compared (baselines, the paper at several n, the engine's own);
- `charts`: the Pareto chart, accuracy by placement, item 6, and the tables of docs/accuracy.md.

`python -m study evaluate [--quick] [--out DIR] [--hdri NAME ...] [--jobs N]` runs it
(`run_command`). Pure NumPy + OpenImageIO (matplotlib for the charts); never bpy.
"""

from __future__ import annotations

import json
import pathlib
import sys

from .study import (
    QUICK,
    Config,
    Results,
    StudyInputError,
    check_claims,
    check_targets,
    hdri_dir,
    ranking,
    ranking_table,
    results_from_json,
    results_to_json,
    run_study,
    with_hdris,
)

__all__ = [
    "QUICK",
    "Config",
    "Results",
    "StudyInputError",
    "check_claims",
    "check_targets",
    "ranking",
    "ranking_table",
    "results_from_json",
    "results_to_json",
    "run_command",
    "run_study",
]


def run_command(quick=False, out=None, hdris=None, jobs=None, log=None) -> Results:
    """The `evaluate` sub-command. Quick: the one-minute subset, printed (and written as
    `OUT/accuracy_quick.json` only when `out` is given). Full: every case, printed, and written
    to `OUT/accuracy.json`, `OUT/images/accuracy_*.png` and the generated tables of
    `OUT/accuracy.md` (when that file exists). `out` defaults to `docs` for the full run.
    Raises StudyInputError on bad input (unknown HDRI, HDRIs not found, unwritable folder)."""
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    config = QUICK if quick else Config()
    if hdris:
        config = with_hdris(config, hdris)
    try:
        folder = hdri_dir()
    except FileNotFoundError as exc:
        raise StudyInputError(str(exc)) from exc
    missing = [n for n in config.hdris if not (folder / f"{n}.exr").is_file()]
    if missing:
        raise StudyInputError(f"no HDRI {missing[0]!r} in {folder}")
    target = pathlib.Path(out) if out else (None if quick else pathlib.Path("docs"))
    if target is not None:
        try:
            (target / "images").mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StudyInputError(f"cannot write in {target}: {exc.strerror}") from exc
    results = run_study(config, log=say, jobs=jobs)
    comparisons = [f"{p}/{t}" for p, t in config.comparisons]
    for comparison in comparisons:
        print(ranking_table(results, comparison))
        print()
    for comparison in comparisons:
        for target_text, measured, holds in check_targets(results, comparison):
            print(f"[{'ok' if holds else 'MISSED'}] {comparison}: {target_text}: {measured}")
    for claim, holds in check_claims(results):
        print(f"[{'ok' if holds else 'FALSE'}] docs claim: {claim}")
    print(f"{results.seconds:.0f} s on {results.machine['cores']} cores")
    if target is None:
        return results
    name = "accuracy_quick.json" if quick else "accuracy.json"
    (target / name).write_text(json.dumps(results_to_json(results), separators=(",", ":")) + "\n")
    say(f"wrote {target / name}")
    if not quick:
        write_charts(results, target)
    return results


def write_charts(results: Results, target) -> None:
    """The charts into `target/images/` and the generated tables into `target/accuracy.md`."""
    from . import charts
    from .baselines import all_methods

    target = pathlib.Path(target)
    images = target / "images"
    charts.chart_pareto(results, images / "accuracy_pareto.png")
    charts.chart_placement(results, images / "accuracy_placement.png")
    if results.auto:
        charts.chart_auto(results, images / "accuracy_auto.png")
    methods, _ = all_methods()
    charts.chart_spheres(results, methods, images / "accuracy_spheres.png")
    blocks = {
        "ranking": charts.table_ranking(results, "exr/hdr"),
        "ranking-ldr": charts.table_ranking(results, "ldr/ldr"),
        "ranking-ldr-hdr": charts.table_ranking(results, "ldr/hdr"),
        "placement": charts.table_by(results, "placement"),
        "placement-plate": charts.table_by(results, "placement", "plate_psnr"),
        "hfov": charts.table_by(results, "hfov"),
        "hdri": charts.table_by(results, "hdri"),
        "targets": charts.table_targets(results),
        "claims": charts.table_claims(results),
    }
    if results.auto:
        blocks["auto"] = charts.table_auto(results)
    if charts.update_markdown(target / "accuracy.md", blocks):
        print(f"updated the tables of {target / 'accuracy.md'}", file=sys.stderr)
    print(f"wrote the charts into {images}", file=sys.stderr)
