"""Summaries, Markdown tables and charts of a 3D-scene run (no bpy; matplotlib's Agg backend)."""

from __future__ import annotations

import math
import pathlib
import re

import numpy as np

from .run import BASELINES, MATERIALS, MEAN, METRICS, PROBE

MARK = "scenes3d"


def method_order(data) -> list:
    return [*data["addon_methods"], PROBE, *[b for b in BASELINES if b != PROBE]]


def _finite_mean(values):
    values = [v for v in values if math.isfinite(v)]
    return float(np.mean(values)) if values else float("nan")


def summary(data) -> dict:
    """{material: {method: {metric: mean, "wins_psnr": n, "wins_ssim": n}}} and Generate times."""
    records = data["scenes"]
    out = {}
    for material, _, _ in MATERIALS:
        out[material] = {}
        for method in method_order(data):
            rows = [r["results"][material][method] for r in records]
            means = {m: _finite_mean([row[m] for row in rows]) for m in METRICS}
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
        "| method | material | PSNR (dB) | SSIM | si-RMSE | beats plate mean (PSNR / SSIM) "
        "| Generate (ms, median) |",
        "|---|---|---|---|---|---|---|",
    ]
    for method in method_order(data):
        for material, _, combine in MATERIALS:
            row = s["materials"][material][method]
            t = s["generate_s"].get(method, {}).get(combine)
            wins = "–" if method == MEAN else f"{row['wins_psnr']}/{n} / {row['wins_ssim']}/{n}"
            lines.append(
                f"| {method} | {material} | {_fmt(row['psnr'])} | {_fmt(row['ssim'], 3)} "
                f"| {_fmt(row['si_rmse'], 3)} | {wins} | "
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


def chart_pareto(data, path) -> None:
    """Mean mirror PSNR against Generate time (median, Replace) per add-on method; the
    baselines (no Generate) as horizontal lines."""
    plt = _plt()
    s = summary(data)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for method in data["addon_methods"]:
        t = 1000 * s["generate_s"][method]["REPLACE"]
        p = s["materials"]["mirror"][method]["psnr"]
        ax.plot([t], [p], "o", ms=8)
        ax.annotate(method, (t, p), textcoords="offset points", xytext=(6, 4))
    styles = {PROBE: ":", "Plate stretched": "-.", MEAN: "--"}
    for baseline in BASELINES:
        ax.axhline(
            s["materials"]["mirror"][baseline]["psnr"],
            ls=styles.get(baseline, "--"),
            color="grey",
            label=f"{baseline} (no Generate)",
        )
    times = [1000 * s["generate_s"][m]["REPLACE"] for m in data["addon_methods"]]
    ax.set_xlim(0, 1.3 * max(times, default=1.0))
    ax.set_xlabel("Generate time, one object, mirror (ms, median over scenes)")
    ax.set_ylabel("mirror subject: mean PSNR (dB)")
    ax.set_title(f"3D scenes ({s['scenes']}): accuracy against time")
    ax.legend(fontsize=8, loc="best")
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
    plt = _plt()
    names = [n for n in (names or pick_example_scenes(data)) if n in crops]
    columns = ["Truth", *data["addon_methods"], PROBE, "Plate stretched", MEAN]
    scores = {r["scene"]["name"]: r["results"]["mirror"] for r in data["scenes"]}
    fig, axes = plt.subplots(
        len(names),
        len(columns),
        figsize=(1.9 * len(columns), 1.9 * len(names) + 0.3),
        squeeze=False,
    )
    for i, name in enumerate(names):
        for j, column in enumerate(columns):
            ax = axes[i, j]
            ax.imshow(np.clip(crops[name][column], 0, 1), interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(column, fontsize=8)
            if column != "Truth":
                m = scores[name][column]
                ax.set_xlabel(f"{m['psnr']:.1f} dB / {m['ssim']:.2f}", fontsize=7)
            else:
                ax.set_xlabel(name, fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
