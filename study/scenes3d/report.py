"""Summaries, Markdown tables and charts of a 3D-scene run (no bpy; matplotlib's Agg backend)."""

from __future__ import annotations

import math
import pathlib
import re
import textwrap

import numpy as np

from .run import BASELINES, MATERIALS, MEAN, METRICS, PROBE

MARK = "scenes3d"


def method_order(data) -> list:
    return [*data["addon_methods"], PROBE, *[b for b in BASELINES if b != PROBE]]


def _finite_mean(values):
    values = [v for v in values if math.isfinite(v)]
    return float(np.mean(values)) if values else float("nan")


def _finite_median(values):
    values = [v for v in values if math.isfinite(v)]
    return float(np.median(values)) if values else float("nan")


def summary(data) -> dict:
    """{material: {method: {metric: mean, "wins_psnr": n, "wins_ssim": n, "detail_median",
    "detail_upper_median"}}} and Generate times. A metric a record lacks (one scored before it
    was added) counts as NaN, which the means leave out."""
    records = data["scenes"]
    out = {}
    for material, _, _ in MATERIALS:
        out[material] = {}
        for method in method_order(data):
            rows = [r["results"][material][method] for r in records]
            means = {m: _finite_mean([row.get(m, math.nan) for row in rows]) for m in METRICS}
            for m in ("detail", "detail_upper"):
                means[f"{m}_median"] = _finite_median([row.get(m, math.nan) for row in rows])
            base = [r["results"][material][MEAN] for r in records]
            means["wins_psnr"] = sum(a["psnr"] > b["psnr"] for a, b in zip(rows, base))
            means["wins_ssim"] = sum(a["ssim"] > b["ssim"] for a, b in zip(rows, base))
            out[material][method] = means
    times = {}
    for method in data["addon_methods"]:
        times[method] = {
            combine: float(np.median([r["generate_s"][method][combine] for r in records]))
            for combine in ("REPLACE", "WORLD")
        }
    return {"materials": out, "generate_s": times, "scenes": len(records)}


def _fmt(v, digits=2):
    return "–" if not math.isfinite(v) else f"{v:.{digits}f}"


def table_means(data) -> str:
    s = summary(data)
    n = s["scenes"]
    lines = [
        "| method | material | PSNR (dB) | SSIM | si-RMSE | FLIP | detail: all / upper (median) "
        "| beats plate mean (PSNR / SSIM) | Generate (ms, median) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for method in method_order(data):
        for material, _, combine in MATERIALS:
            row = s["materials"][material][method]
            t = s["generate_s"].get(method, {}).get(combine)
            wins = "–" if method == MEAN else f"{row['wins_psnr']}/{n} / {row['wins_ssim']}/{n}"
            lines.append(
                f"| {method} | {material} | {_fmt(row['psnr'])} | {_fmt(row['ssim'], 3)} "
                f"| {_fmt(row['si_rmse'], 3)} | {_fmt(row['flip'], 3)} "
                f"| {_fmt(row['detail_median'])} / {_fmt(row['detail_upper_median'])} | {wins} | "
                f"{'–' if t is None else f'{1000 * t:.0f} ({combine.lower()})'} |"
            )
    return "\n".join(lines) + "\n"


def table_scenes(data) -> str:
    """Mirror PSNR per scene and method, with the method's margin over the plate mean."""
    methods = method_order(data)
    lines = [
        "| scene | HDRI | lens (mm) | distance (m) | size (m) | pitch (°) | "
        + " | ".join(methods)
        + " |",
        "|---|---|---|---|---|---|" + "---|" * len(methods),
    ]
    for r in data["scenes"]:
        sc = r["scene"]
        mirror = r["results"]["mirror"]
        cells = []
        for m in methods:
            v = mirror[m]["psnr"]
            mark = "" if m == MEAN else (" ✓" if v > mirror[MEAN]["psnr"] else "")
            cells.append(f"{_fmt(v, 1)}{mark}")
        lines.append(
            f"| {sc['name']} | {sc['hdri']} | {sc['lens_mm']:.0f} | {sc['distance']:.1f} | "
            f"{sc['size']:.2f} | {sc['pitch_deg']:.1f} | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines) + "\n"


def table_shapes(data) -> str:
    methods = method_order(data)
    shapes = sorted({r["scene"]["shape"] for r in data["scenes"]})
    lines = [
        "| shape | scenes | " + " | ".join(methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for shape in shapes:
        rows = [r for r in data["scenes"] if r["scene"]["shape"] == shape]
        cells = []
        for m in methods:
            p = _finite_mean([r["results"]["mirror"][m]["psnr"] for r in rows])
            q = _finite_mean([r["results"]["mirror"][m]["ssim"] for r in rows])
            cells.append(f"{_fmt(p, 1)} / {_fmt(q, 2)}")
        lines.append(f"| {shape} | {len(rows)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def blocks(data) -> dict:
    return {
        "means": table_means(data),
        "scenes": table_scenes(data),
        "shapes": table_shapes(data),
    }


def update_markdown(path, blocks_: dict, header: str) -> None:
    """Replace each `<!-- scenes3d:NAME -->...<!-- /scenes3d:NAME -->` block of ``path``; a new
    file gets ``header`` and every block."""
    path = pathlib.Path(path)
    if not path.is_file():
        body = header
        for name, text in blocks_.items():
            body += f"\n<!-- {MARK}:{name} -->\n{text.rstrip()}\n<!-- /{MARK}:{name} -->\n"
        path.write_text(body)
        return
    text = path.read_text()
    for name, body in blocks_.items():
        pattern = re.compile(
            rf"(<!-- {MARK}:{re.escape(name)} -->\n).*?(<!-- /{MARK}:{re.escape(name)} -->)", re.S
        )
        text = pattern.sub(lambda m, b=body: m.group(1) + b.rstrip() + "\n" + m.group(2), text)
    path.write_text(text)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


PARETO_METRICS = (  # (metric, axis label): the panels of chart_pareto
    ("psnr", "mirror subject: mean PSNR (dB)"),
    ("flip", "mirror subject: mean FLIP (lower is better)"),
)


def chart_pareto(data, path) -> None:
    """Mean mirror PSNR, and mean FLIP, against Generate time (median, Replace) per add-on
    method; the baselines (no Generate) as horizontal lines. A metric no record holds (a run
    before it was added) gets no panel."""
    plt = _plt()
    s = summary(data)
    mirror = s["materials"]["mirror"]
    panels = [
        (m, label)
        for m, label in PARETO_METRICS
        if any(math.isfinite(mirror[method].get(m, math.nan)) for method in mirror)
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(6.4 * len(panels), 4.0), squeeze=False)
    times = [1000 * s["generate_s"][m]["REPLACE"] for m in data["addon_methods"]]
    right = 1.3 * max(times, default=1.0)
    styles = {PROBE: ":", "Plate stretched": "-.", MEAN: "--"}
    for ax, (metric, label) in zip(axes[0], panels):
        for method, t in zip(data["addon_methods"], times):
            p = mirror[method][metric]
            ax.plot([t], [p], "o", ms=8)
            left = t > 0.5 * right  # a label that would run off the chart goes to the left
            ax.annotate(
                method,
                (t, p),
                textcoords="offset points",
                xytext=(-6 if left else 6, 4),
                ha="right" if left else "left",
            )
        for baseline in BASELINES:
            ax.axhline(
                mirror[baseline][metric],
                ls=styles.get(baseline, "--"),
                color="grey",
                label=f"{baseline} (no Generate)",
            )
        ax.set_xlim(0, right)
        low, high = ax.get_ylim()
        ax.set_ylim(low, high + 0.08 * (high - low))  # room for the top point's label
        ax.set_xlabel("Generate time, one object, mirror (ms, median over scenes)")
        ax.set_ylabel(label)
        ax.set_title(f"3D scenes ({s['scenes']}): accuracy against time")
        ax.legend(fontsize=8, loc="lower right" if metric == "psnr" else "upper right")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def pick_example_scenes(data, count=3) -> list:
    """Up to ``count`` scenes with different shapes (a sphere, Suzanne and the car first)."""
    chosen, seen = [], set()
    for shape in ("sphere", "suzanne", "car", "torus"):
        for r in data["scenes"]:
            if r["scene"]["shape"] == shape and shape not in seen:
                chosen.append(r["scene"]["name"])
                seen.add(shape)
                break
    for r in data["scenes"]:  # fewer shapes than wanted: fill with the rest
        if len(chosen) >= count:
            break
        if r["scene"]["name"] not in chosen:
            chosen.append(r["scene"]["name"])
    return chosen[:count]


def contact_sheet(data, crops, path, names=None) -> None:
    """Rows: scenes; columns: truth | the add-on's methods | on-set probe | plate stretched |
    plate mean, each cropped around the mirror subject and composited over the plate."""
    names = [n for n in (names or pick_example_scenes(data)) if n in crops]
    columns = ["Truth", *data["addon_methods"], PROBE, "Plate stretched", MEAN]
    scores = {r["scene"]["name"]: r["results"]["mirror"] for r in data["scenes"]}

    def label(name, column):
        if column == "Truth":
            return name, 6
        m = scores[name][column]
        return f"{m['psnr']:.1f} dB / {m['ssim']:.2f}", 7

    def title(column):  # long method names on two lines: the columns are 1.9 inches wide
        return "\n".join(textwrap.wrap(column, 24))

    _image_grid(crops, names, columns, (1.9, 1.9, 0.3), (title, 8), label, path)


def _image_grid(crops, names, columns, cell, title, label, path) -> None:
    """A grid of crops (rows ``names``, columns ``columns``) saved to ``path``. cell: (width,
    height, extra height) in inches; title: (column -> title, font size); label: (name,
    column) -> (text under the image, font size)."""
    plt = _plt()
    fig = _grid_figure(crops, names, columns, cell, title, label)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _grid_figure(crops, names, columns, cell, title, label):
    """`_image_grid`'s figure, not saved."""
    plt = _plt()
    width, height, extra = cell
    fig, axes = plt.subplots(
        len(names),
        len(columns),
        figsize=(width * len(columns), height * len(names) + extra),
        squeeze=False,
    )
    for i, name in enumerate(names):
        for j, column in enumerate(columns):
            ax = axes[i, j]
            ax.imshow(np.clip(crops[name][column], 0, 1), interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(title[0](column), fontsize=title[1])
            text, size = label(name, column)
            ax.set_xlabel(text, fontsize=size)
    fig.tight_layout()
    return fig


SHEET_COLUMNS = ("Truth", "default", PROBE, MEAN)  # "default": the add-on's default method
SHEET_TITLES = {
    "Truth": "Truth (path-traced)",
    "default": "Default: Camera View +\nGround (Auto)",
    PROBE: "On-set probe\n(the true HDRI)",
    MEAN: "Plate mean\n(a flat colour)",
}


def sheet_figure(rows: list, default: str):
    """The mirror sheet (issue 41, item 7): one row per scene, the columns SHEET_COLUMNS, each
    cell a crop around the mirror subject, its mirror PSNR and FLIP printed under it (the
    truth's: the scene's name and set). ``rows``: [(name, set label, {column: display crop},
    {column: {"psnr", "flip"}})], the add-on's method under the key ``default``. Returns the
    matplotlib figure."""
    crops = {name: {c: images[default if c == "default" else c] for c in SHEET_COLUMNS}
             for name, _, images, _ in rows}  # fmt: skip
    tags = {name: tag for name, tag, _, _ in rows}
    scores = {name: values for name, _, _, values in rows}

    def label(name, column):
        if column == "Truth":
            return f"{name}\n({tags[name]})", 7
        m = scores[name][default if column == "default" else column]
        return f"{m['psnr']:.1f} dB  FLIP {m['flip']:.2f}", 8

    names = [name for name, _, _, _ in rows]
    return _grid_figure(crops, names, SHEET_COLUMNS, (2.1, 2.1, 0.4), (SHEET_TITLES.get, 9), label)


def write_sheet(rows: list, default: str, path) -> None:
    """`sheet_figure` saved as a PNG at ``path``."""
    plt = _plt()
    fig = sheet_figure(rows, default)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --- the failure cases (issue 11, item 5) -------------------------------------------------------

CASE_NOTES = {
    "f1": "floating 0.75 m above the ground",
    "f2": "camera looking up 15°, the sphere on a 2.5 m column: no ground in the plate",
    "f3": "a wall 2 m ahead fills the plate; the sphere on a pedestal before it",
    "f4": "at the frame's right border",
    "f5": "covering most of the plate (2.2 m, 3.3 m away)",
    "f6": "0.15 m at 8 m, 4 % of the frame's height",
}
CAMERA_VIEW = "Camera View"


def _case(record) -> str:
    return record["scene"].get("case") or record["scene"]["name"]


def degradation(record, default) -> str:
    """One line: the default against the plate mean and Camera View on the mirror."""
    mirror = record["results"]["mirror"]
    d, mean = mirror[default], mirror[MEAN]
    line = (
        f"{d['psnr'] - mean['psnr']:+.1f} dB / {d['ssim'] - mean['ssim']:+.2f} SSIM "
        "against the plate mean"
    )
    if CAMERA_VIEW in mirror and CAMERA_VIEW != default:
        line += f", {d['psnr'] - mirror[CAMERA_VIEW]['psnr']:+.1f} dB against Camera View"
    return line


def _warned(record, default) -> str:
    """The default's warnings about the subject (World mode repeats them), or –."""
    lines = [w for w in record.get("warnings", {}).get(default, []) if w.startswith("Subject")]
    return "; ".join(dict.fromkeys(lines)) or "–"


def table_failures(data) -> str:
    """Per failure case: every method's mirror PSNR / SSIM and how the default degrades."""
    methods = method_order(data)
    default = data.get("default_method", data["addon_methods"][0])
    lines = [
        "| case | subject px | "
        + " | ".join(methods)
        + f" | how the default ({default}) degrades | the add-on warns |",
        "|---|---|" + "---|" * (len(methods) + 2),
    ]
    for r in data["scenes"]:
        case = _case(r)
        note = CASE_NOTES.get(case[:2], "")
        mirror = r["results"]["mirror"]
        cells = [f"{_fmt(mirror[m]['psnr'], 1)} / {_fmt(mirror[m]['ssim'], 2)}" for m in methods]
        lines.append(
            f"| {case}: {note} | {r['subject_pixels']} | "
            + " | ".join(cells)
            + f" | {degradation(r, default)} | {_warned(r, default)} |"
        )
    return "\n".join(lines) + "\n"


def chart_failures(data, path) -> None:
    """Mirror PSNR per failure case, one bar per method."""
    plt = _plt()
    methods = method_order(data)
    cases = [_case(r) for r in data["scenes"]]
    fig, ax = plt.subplots(figsize=(9.0, 4.0))
    width = 0.8 / len(methods)
    for k, m in enumerate(methods):
        values = [r["results"]["mirror"][m]["psnr"] for r in data["scenes"]]
        ax.bar(np.arange(len(cases)) + (k - (len(methods) - 1) / 2) * width, values, width, label=m)
    ax.set_xticks(np.arange(len(cases)), cases, fontsize=8)
    ax.set_ylabel("mirror subject: PSNR (dB)")
    ax.set_title("Failure cases: mirror PSNR per method")
    ax.legend(fontsize=7, ncol=2, loc="best")
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def add_failures_block(path, table: str, command: str) -> None:
    """Rewrite the `failures` block of ``path``; a file without it gets the heading "Where it
    fails" and the block at its end (a missing file: just those)."""
    add_block(path, "failures", "Where it fails", table, command)


def add_block(path, name: str, heading: str, table: str, command: str) -> None:
    """Rewrite the block ``name`` of ``path``; a file without it gets ``heading`` and the
    block at its end (a missing file: just those)."""
    path = pathlib.Path(path)
    marker = f"<!-- {MARK}:{name} -->"
    text = path.read_text() if path.is_file() else ""
    if marker not in text:
        text = (
            text.rstrip()
            + ("\n\n" if text else "")
            + (f"## {heading}\n\nGenerated by `{command}`.\n\n{marker}\n<!-- /{MARK}:{name} -->\n")
        )
        path.write_text(text)
    update_markdown(path, {name: table}, "")


# --- inter-reflections (issue 11, item 4) -------------------------------------------------------

ONE, PLAIN, AUTO = "one pass", "auto, maps as built", "auto"  # as inter.py (which imports bpy)
RUNS = (ONE, PLAIN, AUTO)
BLIND = "truth without inter-reflections"
CEILING = "one pass, inter pixels exact"
TRACED_BLIND = "ray traced, mirrors blind"


def inter_summary(data) -> dict:
    """{method: {run: mean scores over the cases (all the mirrors' pixels), run + " inter":
    mean PSNR on the pixels where the truth shows the mirrors in each other, "gain_psnr",
    "gain_ssim": auto - one pass, "better": cases where auto's PSNR is above one pass's,
    "passes": [r per case]}}."""
    out = {}
    for method in data["addon_methods"]:
        rows = [r["passes"][method] for r in data["scenes"]]
        entry = {
            run: {m: _finite_mean([row[run].get(m, math.nan) for row in rows]) for m in METRICS}
            for run in RUNS
        }
        for run in RUNS:
            entry[run + " inter"] = _finite_mean(
                [row[run]["inter"]["psnr"] for row in rows if row[run].get("inter")]
            )
        entry["gain_psnr"] = entry[AUTO]["psnr"] - entry[ONE]["psnr"]
        entry["ceiling_psnr"] = _finite_mean(
            [row[CEILING]["psnr"] - row[ONE]["psnr"] for row in rows if CEILING in row]
        )
        entry["gain_ssim"] = entry[AUTO]["ssim"] - entry[ONE]["ssim"]
        entry["better"] = sum(row[AUTO]["psnr"] > row[ONE]["psnr"] for row in rows)
        entry["worst_psnr"] = min(row[AUTO]["psnr"] - row[ONE]["psnr"] for row in rows)
        entry["passes"] = [row[AUTO]["passes"] for row in rows]
        out[method] = entry
    return out


def _pair(scores) -> str:
    return f"{_fmt(scores['psnr'])} / {_fmt(scores['ssim'], 3)}"


def _inter_psnr(scores) -> str:
    return _fmt(scores["inter"]["psnr"]) if scores.get("inter") else "–"


def _signed(v) -> str:
    return "–" if not math.isfinite(v) else f"{v:+.2f} dB"


def _ceiling(runs) -> str:
    if CEILING not in runs:
        return "–"
    return f"{runs[CEILING]['psnr'] - runs[ONE]['psnr']:+.2f} dB"


def table_inter(data) -> str:
    """Per case and method: PSNR / SSIM on all the mirrors' pixels of one pass, the passes with
    the maps as Generate builds them, and with the neighbours placed (auto, r); PSNR on the
    pixels where the truth shows the mirrors in each other; then the means per method."""
    methods = data["addon_methods"]
    lines = [
        "| case | mirrors: px (inter px) | method | one pass | auto, maps as built (r) |"
        " auto (r) | auto − one pass | inter px PSNR: one / as built / auto |"
        " plate mean | mirrors blind to each other |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in data["scenes"]:
        mirror = r["results"]["mirror"]
        for k, method in enumerate(methods):
            runs = r["passes"][method]
            one, plain, auto = runs[ONE], runs[PLAIN], runs[AUTO]
            first = k == 0
            head = (
                f"| {_case(r)} | {r['mirrors']}: {r['subject_pixels']} ({r['inter_pixels']}) |"
                if first
                else "| | |"
            )
            tail = f" {_pair(mirror[MEAN])} | {_pair(mirror[BLIND])} |" if first else " | |"
            lines.append(
                f"{head} {method} | {_pair(one)} | {_pair(plain)} ({plain['passes']}) | "
                f"{_pair(auto)} ({auto['passes']}) | "
                f"{auto['psnr'] - one['psnr']:+.2f} dB / {auto['ssim'] - one['ssim']:+.3f} | "
                f"{_ceiling(runs)} | "
                f"{_inter_psnr(one)} / {_inter_psnr(plain)} / {_inter_psnr(auto)} |" + tail
            )
    s = inter_summary(data)
    n = len(data["scenes"])
    lines += [
        "",
        "| method (mean of the cases) | one pass | auto, maps as built | auto |"
        " auto − one pass | at most (inter px exact) | auto above one pass (PSNR) |"
        " inter px PSNR: one / as built / auto | worst case: auto − one pass |"
        " FLIP: one / auto | r per case |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method in methods:
        e = s[method]
        lines.append(
            f"| {method} | {_pair(e[ONE])} | {_pair(e[PLAIN])} | {_pair(e[AUTO])} | "
            f"{e['gain_psnr']:+.2f} dB / {e['gain_ssim']:+.3f} | {_signed(e['ceiling_psnr'])} | "
            f"{e['better']}/{n} | "
            f"{_fmt(e[ONE + ' inter'])} / {_fmt(e[PLAIN + ' inter'])} / "
            f"{_fmt(e[AUTO + ' inter'])} | {e['worst_psnr']:+.2f} dB | "
            f"{_fmt(e[ONE]['flip'], 3)} / {_fmt(e[AUTO]['flip'], 3)} | "
            f"{', '.join(map(str, e['passes']))} |"
        )
    return "\n".join(lines) + "\n"


def table_traced(data) -> str:
    """The default method's ray-traced pass (its auto) against one pass and against the same
    render with the mirrors blind to each other, per case and on average: PSNR / SSIM on all
    the mirrors' pixels (PSNR on the inter px in brackets). Empty when no case traced it."""
    method = data.get("default_method")
    rows = [r for r in data["scenes"] if TRACED_BLIND in r["passes"].get(method, {})]
    if not rows:
        return ""
    runs = (ONE, AUTO, TRACED_BLIND)

    def cell(scores, inter):
        return f"{_pair(scores)} ({_fmt(inter)})"

    lines = [
        "| case | mirrors: px (inter px) | one pass | ray traced (auto) | ray traced, mirrors "
        "blind | ray traced − one pass | ray traced − blind, inter px |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        p = r["passes"][method]
        lines.append(
            f"| {_case(r)} | {r['mirrors']}: {r['subject_pixels']} ({r['inter_pixels']}) | "
            + " | ".join(cell(p[run], p[run]["inter"]["psnr"]) for run in runs)
            + f" | {p[AUTO]['psnr'] - p[ONE]['psnr']:+.2f} dB | "
            f"{p[AUTO]['inter']['psnr'] - p[TRACED_BLIND]['inter']['psnr']:+.2f} dB |"
        )
    mean = {
        run: {
            m: _finite_mean([r["passes"][method][run][m] for r in rows]) for m in ("psnr", "ssim")
        }
        for run in runs
    }
    inter = {
        run: _finite_mean([r["passes"][method][run]["inter"]["psnr"] for r in rows]) for run in runs
    }
    ahead = sum(r["passes"][method][AUTO]["psnr"] > r["passes"][method][ONE]["psnr"] for r in rows)
    lines.append(
        "| mean | | "
        + " | ".join(cell(mean[run], inter[run]) for run in runs)
        + f" | {mean[AUTO]['psnr'] - mean[ONE]['psnr']:+.2f} dB, ahead in {ahead}/{len(rows)} | "
        f"{inter[AUTO] - inter[TRACED_BLIND]:+.2f} dB |"
    )
    return "\n".join(lines) + "\n"


def contact_sheet_inter(data, crops, path) -> None:
    """Rows: cases; columns: truth, then one pass and auto per add-on method, cropped around
    the mirrors and composited over the plate."""
    names = [r["scene"]["name"] for r in data["scenes"] if r["scene"]["name"] in crops]
    columns = ["Truth", BLIND] + [
        f"{m}: {run}" for m in data["addon_methods"] for run in (ONE, AUTO)
    ]
    records = {r["scene"]["name"]: r for r in data["scenes"]}

    def title(column):
        return column.replace(": ", "\n").replace(" without", "\nwithout")

    def label(name, column):
        if column == "Truth":
            return _case(records[name]), 6
        if column == BLIND:
            m = records[name]["results"]["mirror"][BLIND]
        else:
            method, run = column.split(": ")
            m = records[name]["passes"][method][run]
        return f"{m['psnr']:.2f} dB / {m['ssim']:.3f}", 6

    _image_grid(crops, names, columns, (2.2, 1.5, 0.4), (title, 7), label, path)
