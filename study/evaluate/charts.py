"""Charts (PNG, matplotlib's Agg backend) and Markdown tables of an accuracy study.

- `accuracy_pareto.png`: accuracy against time per method and setting, with the Pareto front;
- `accuracy_placement.png`: accuracy by object placement and size (where each method fails);
- `accuracy_auto.png`: item 6, map resolution from the object's size and cheap rough/diffuse light;
- `accuracy_spheres.png`: the spheres themselves for one case, truth and each method.

`update_markdown` rewrites the generated blocks of docs/accuracy.md (between
`<!-- evaluate:NAME -->` and `<!-- /evaluate:NAME -->`), leaving the prose alone.
"""

from __future__ import annotations

import math
import pathlib
import re

import numpy as np

from . import metrics as M
from . import spheres as S
from .study import (
    HIGHER_IS_BETTER,
    PLACEMENTS,
    Results,
    check_claims,
    check_targets,
    make_view,
    object_direction,
    ranking,
    records_for,
    summarise,
    win_rate,
)

FAMILY_COLOUR = {"baseline": "#7f7f7f", "paper": "#1f77b4", "engine": "#d62728"}
BASELINE_COLOURS = {
    "grey": "#bdbdbd",
    "plate mean": "#2ca02c",
    "stretched plate": "#9467bd",
    "agusanto blur": "#8c564b",
}
REFERENCE_COLOUR = "#17becf"
METRIC_LABEL = {
    "mirror_psnr": "mirror-sphere PSNR (dB, LDR)",
    "mirror_ssim": "mirror-sphere SSIM (LDR)",
    "mirror_si_rmse": "mirror-sphere si-RMSE",
    "glossy_psnr": "matte-silver PSNR (dB, LDR)",
    "glossy_si_rmse": "matte-silver si-RMSE",
    "glossy_angular": "matte-silver RGB angle (deg)",
    "diffuse_psnr": "diffuse-sphere PSNR (dB, LDR)",
    "diffuse_si_rmse": "diffuse-sphere si-RMSE",
    "diffuse_angular": "diffuse-sphere RGB angle (deg)",
    "mirror_angular": "mirror-sphere RGB angle (deg)",
    "plate_psnr": "PSNR where the plate sees (dB)",
}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _colour(results: Results, name: str) -> str:
    family = {m["name"]: m["family"] for m in results.methods}[name]
    if family == "baseline":
        return BASELINE_COLOURS.get(name, FAMILY_COLOUR["baseline"])
    if family == "paper":
        return FAMILY_COLOUR["paper"]
    if family == "reference":
        return REFERENCE_COLOUR
    engines = [m["name"] for m in results.methods if m["family"] == "engine"]
    shades = ["#d62728", "#ff7f0e", "#e377c2", "#bcbd22", "#7f7f00"]
    return shades[engines.index(name) % len(shades)]


def pareto_front(times, values, higher_is_better=True):
    """Indices of the Pareto-optimal points (no other point is both faster and better),
    sorted by time."""
    order = sorted(
        range(len(times)), key=lambda i: (times[i], -values[i] if higher_is_better else values[i])
    )
    front, best = [], -math.inf
    for i in order:
        v = values[i] if higher_is_better else -values[i]
        if v > best:
            front.append(i)
            best = v
    return front


def chart_pareto(results: Results, path, comparison: str = "exr/hdr") -> None:
    """Accuracy against the median cold time of one map, per method, with the Pareto front."""
    plt = _plt()
    summary = summarise(results, comparison)
    names = [n for n in summary if n in results.timing]
    times = [max(results.timing[n]["cold_ms"], 1e-3) for n in names]
    metrics = ("mirror_psnr", "mirror_ssim", "diffuse_si_rmse")
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    for ax, metric in zip(axes, metrics):
        values = [summary[n][metric] for n in names]
        for n, t, v in zip(names, times, values):
            star = n == results.default
            ax.scatter(
                t,
                v,
                s=140 if star else 40,
                marker="*" if star else "o",
                color=_colour(results, n),
                zorder=3,
                edgecolor="black",
                linewidth=0.4,
            )
            if n.startswith("paper"):  # every n lands on the same spot: one label
                if n != "paper n=inf":
                    continue
                n = "paper, n = 4 ... inf"
            ax.annotate(n, (t, v), textcoords="offset points", xytext=(5, 3), fontsize=7)
        front = pareto_front(times, values, HIGHER_IS_BETTER[metric])
        ax.step(
            [times[i] for i in front],
            [values[i] for i in front],
            where="post",
            color="black",
            alpha=0.5,
            linewidth=1,
            zorder=2,
            label="Pareto front",
        )
        ax.set_xscale("log")
        ax.set_xlabel("median time per map, new bounds (ms, log)")
        better = "higher" if HIGHER_IS_BETTER[metric] else "lower"
        ax.set_ylabel(f"{METRIC_LABEL[metric]} — {better} is better")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    n_cases = len(
        {
            (r["hdri"], r["heading"], r["hfov"], r["placement"])
            for r in records_for(results, comparison)
        }
    )
    fig.suptitle(
        f"Accuracy against time, mean over {n_cases} cases ({comparison.replace('/', ' plate, ')}"
        f" truth); star: the product's default",
        fontsize=11,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _chart_methods(results: Results) -> list:
    """The methods worth a line in per-placement charts: baselines, the paper's continuous
    limit and its worst n, and every engine method."""
    names = [m["name"] for m in results.methods]
    keep = [n for n in names if n in ("grey", "plate mean", "stretched plate", "agusanto blur")]
    keep += [m["name"] for m in results.methods if m["family"] == "reference"]
    keep += [n for n in ("paper n=inf", "paper n=4") if n in names]
    keep += [m["name"] for m in results.methods if m["family"] == "engine"]
    return keep


def chart_placement(results: Results, path, comparison: str = "exr/hdr") -> None:
    """Where each method fails: accuracy by placement (and size), and by field of view."""
    plt = _plt()
    by = summarise(results, comparison, by="placement")
    order = [p.name for p in PLACEMENTS if any(p.name in by[m] for m in by)]
    names = _chart_methods(results)
    fig, axes = plt.subplots(2, 2, figsize=(15, 9.5))
    x = np.arange(len(order))
    panels = (
        (axes[0, 0], "mirror_psnr", None, "mirror-sphere PSNR (dB)"),
        (axes[0, 1], "mirror_psnr", "plate mean", "mirror PSNR minus the plate mean's (dB)"),
        (axes[1, 0], "plate_psnr", None, "PSNR where the plate sees (dB)"),
    )
    for ax, metric, relative, label in panels:
        for n in names:
            ys = [by[n][g][metric] - (by[relative][g][metric] if relative else 0.0) for g in order]
            star = n == results.default
            ax.plot(
                x,
                ys,
                marker="*" if star else "o",
                markersize=10 if star else 5,
                color=_colour(results, n),
                linestyle="-" if star else "--",
                linewidth=2 if star else 1,
                label=n,
            )
        ax.set_xticks(x, order, rotation=20)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0, 1].axhline(-1.0, color="red", linewidth=1, linestyle=":", label="target: -1 dB")
    axes[1, 0].axhline(40.0, color="red", linewidth=1, linestyle=":", label="target: 40 dB")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=8, frameon=False)
    # by field of view
    ax = axes[1, 1]
    byfov = summarise(results, comparison, by="hfov")
    fovs = sorted({g for m in byfov for g in byfov[m]})
    for n in names:
        star = n == results.default
        ax.plot(
            fovs,
            [byfov[n][f]["mirror_psnr"] for f in fovs],
            marker="*" if star else "o",
            color=_colour(results, n),
            linestyle="-" if star else "--",
            linewidth=2 if star else 1,
            label=n,
        )
    ax.set_xticks(fovs, [f"{f:.0f}°" for f in fovs])
    ax.set_xlabel("horizontal field of view of the plate")
    ax.set_ylabel("mirror-sphere PSNR (dB)")
    ax.grid(alpha=0.3)
    axes[0, 1].text(
        0.01, 0.02, "dotted: target -1 dB", transform=axes[0, 1].transAxes, color="red", fontsize=8
    )
    axes[1, 0].text(
        0.01, 0.9, "dotted: target 40 dB", transform=axes[1, 0].transAxes, color="red", fontsize=8
    )
    fig.suptitle(
        f"Where methods fail: by object placement and size, and by field of view "
        f"({comparison.replace('/', ' plate, ')} truth)",
        fontsize=11,
    )
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def auto_summary(auto: dict) -> dict:
    """Means over HDRIs of the resolution study per object size, and of the rough study."""
    widths = [str(w) for w in auto["widths"]]
    sizes = sorted({r["object_px"] for r in auto["resolution"]})
    res = {}
    for d in sizes:
        rows = [r for r in auto["resolution"] if r["object_px"] == d]
        res[d] = {
            key: {w: float(np.mean([r[key][w] for r in rows])) for w in widths}
            for key in ("psnr", "self_psnr", "truth_psnr")
        }
        res[d]["auto_width"] = rows[0]["auto_width"]
        res[d]["placements"] = sorted({r["placement"] for r in rows})
    names = [k for k in auto["rough"][0] if k not in ("hdri", "placement")]
    rough = {
        n: {m: float(np.mean([e[n][m] for e in auto["rough"]])) for m in ("psnr", "si_rmse")}
        for n in names
    }
    return {"resolution": res, "rough": rough}


def chart_auto(results: Results, path) -> None:
    """Item 6: map width against accuracy and cost per object size; cheap rough/diffuse light."""
    plt = _plt()
    auto = results.auto
    summ = auto_summary(auto)
    widths = auto["widths"]
    cost = [auto["width_cost"][str(w)]["cold_ms"] for w in widths]
    fig, axes = plt.subplots(1, 3, figsize=(17, 5))
    _auto_width_panels(plt, axes, summ, widths, cost)
    _auto_rough_panel(axes[2], summ, auto)
    fig.suptitle(
        f"Model no more than a scene needs ({auto['method']}, float plates, HDR truth)", fontsize=11
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _auto_width_panels(plt, axes, summ, widths, cost) -> None:
    """`chart_auto`'s first two panels: per object size, PSNR against the method's widest map
    and the true map's (left), against the truth less the best width's with the cold time per
    map (right); a star at the automatic width."""
    cmap = plt.get_cmap("viridis")
    sizes = sorted(summ["resolution"])
    for k, d in enumerate(sizes):
        entry = summ["resolution"][d]
        colour = cmap(k / max(1, len(sizes) - 1))
        self_p = [min(entry["self_psnr"][str(w)], 70.0) for w in widths]
        truth_p = [min(entry["truth_psnr"][str(w)], 70.0) for w in widths]
        gap = [entry["psnr"][str(w)] - max(entry["psnr"].values()) for w in widths]
        axes[0].plot(widths, self_p, marker="o", color=colour, label=f"{d} px: method's own map")
        axes[0].plot(
            widths, truth_p, marker="s", color=colour, linestyle=":", label=f"{d} px: true map"
        )
        aw = entry["auto_width"]
        axes[0].scatter(
            [aw],
            [min(entry["self_psnr"][str(aw)], 70.0)],
            s=220,
            marker="*",
            color=colour,
            edgecolor="black",
            zorder=4,
        )
        axes[1].plot(widths, gap, marker="o", color=colour, label=f"object {d} px")
        axes[1].scatter(
            [aw],
            [entry["psnr"][str(aw)] - max(entry["psnr"].values())],
            s=220,
            marker="*",
            color=colour,
            edgecolor="black",
            zorder=4,
        )
    axes[0].axhline(40.0, color="red", linestyle=":", linewidth=1)
    axes[0].set_ylabel("PSNR against the 2048-wide map (dB)")
    axes[0].set_title("mirror sphere at the object's size on screen", fontsize=9)
    axes[1].axhline(-0.2, color="red", linestyle=":", linewidth=1, label="-0.2 dB")
    axes[1].set_ylabel("PSNR against the truth minus the best width's (dB)")
    axes[1].set_title("the same sphere against the truth", fontsize=9)
    for ax in axes[:2]:
        ax.set_xscale("log", base=2)
        ax.set_xticks(widths, [str(w) for w in widths])
        ax.set_xlabel("lat-long width (star: automatic choice)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    ax2 = axes[1].twinx()
    ax2.plot(widths, cost, color="black", alpha=0.4, linestyle="--", marker=".")
    ax2.set_yscale("log")
    ax2.set_ylabel("cold time per map (ms, dashed)")


def _auto_rough_panel(ax, summ, auto) -> None:
    """`chart_auto`'s third panel: each rough and diffuse candidate's PSNR less the full map's,
    labelled with its milliseconds per object."""
    rough = summ["rough"]
    names = list(rough)
    costs = [auto["rough_cost_ms"][n] for n in names]
    ref = {"glossy": rough["glossy full map"]["psnr"], "diffuse": rough["diffuse full map"]["psnr"]}
    deltas = [rough[n]["psnr"] - ref[n.split()[0]] for n in names]
    bars = ax.barh(
        names, deltas, color=["#1f77b4" if n.startswith("glossy") else "#2ca02c" for n in names]
    )
    for bar, c in zip(bars, costs):
        ax.annotate(
            f"{c:.0f} ms",
            (bar.get_width(), bar.get_y() + bar.get_height() / 2),
            xytext=(4, -3),
            textcoords="offset points",
            fontsize=8,
        )
    ax.axvline(-0.2, color="red", linestyle=":", linewidth=1)
    ax.axvline(0.0, color="black", linewidth=0.8)
    ax.set_xlabel("PSNR minus the full map's (dB)")
    ax.set_title("rough and diffuse light (label: ms per object)", fontsize=9)
    ax.invert_yaxis()
    ax.grid(alpha=0.3, axis="x")


def chart_spheres(
    results: Results, methods, path, hdri="courtyard", placement="off-centre", hfov=60.0
) -> None:
    """The plate, then the truth and each method as mirror / matte-silver / diffuse spheres."""
    plt = _plt()
    from .study import HEADING_OFFSET, Config

    config = Config(
        **{k: (tuple(v) if isinstance(v, list) else v) for k, v in results.config.items()}
    )
    heading = HEADING_OFFSET.get(hdri, 0.0) + config.headings[0]
    view = make_view(hdri, heading, config.pitch, hfov, config.plate_size, config.map_width)
    place = {p.name: p for p in PLACEMENTS}[placement]
    bbox = place.bbox(*config.plate_size)
    probe = S.Probe(
        config.sphere_size, S.object_view(object_direction(bbox, config.plate_size, hfov))
    )
    keep = ["truth"] + [n for n in _chart_methods(results) if n != "paper n=4"]
    by_name = {m.name: m for m in methods}
    fig, axes = plt.subplots(4, len(keep) + 1, figsize=(1.9 * (len(keep) + 1), 7.6))
    axes[0, 0].imshow(M.to_display(view.plates["exr"]))
    x0, y0, x1, y1 = bbox
    axes[0, 0].plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="red", linewidth=0.8)
    axes[0, 0].set_title("plate and object", fontsize=8)
    for i in range(4):
        axes[i, 0].set_axis_off()
    for j, n in enumerate(keep, start=1):
        env = (
            view.truths["hdr"]
            if n == "truth"
            else by_name[n].fn(view.plates["exr"], bbox, hfov, config.map_width)
        )
        mirror, glossy, diffuse = probe.render(env)
        axes[0, j].imshow(M.to_display(env))
        for i, img in enumerate((mirror, glossy, diffuse), start=1):
            axes[i, j].imshow(M.to_display(img))
        axes[0, j].set_title(n + (" *" if n == results.default else ""), fontsize=8)
        for i in range(4):
            axes[i, j].set_xticks([])
            axes[i, j].set_yticks([])
    for i, label in enumerate(("lat-long map", "mirror", "matte silver", "diffuse (SH9)")):
        axes[i, 1].set_ylabel(label, fontsize=9)
    fig.suptitle(
        f"{hdri}, {placement} object, hfov {hfov:.0f}°: the true surroundings and each method's "
        "map (camera frame), and their spheres seen from the camera (* the default)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=100)
    plt.close(fig)


# --- Markdown tables -----------------------------------------------------------------------


def _fmt(v, metric):
    if metric.endswith("psnr"):
        return f"{v:.2f}"
    if metric.endswith("angular"):
        return f"{v:.1f}"
    return f"{v:.3f}"


def table_ranking(results: Results, comparison: str = "exr/hdr") -> str:
    summary = summarise(results, comparison)
    cols = (
        "mirror_psnr",
        "mirror_ssim",
        "mirror_angular",
        "glossy_si_rmse",
        "diffuse_si_rmse",
        "diffuse_angular",
        "plate_psnr",
    )
    head = (
        "| method | mirror PSNR | mirror SSIM | mirror angle | matte si-RMSE | diffuse si-RMSE "
        "| diffuse angle | plate PSNR | beats plate mean | ms (cold / warm) |"
    )
    lines = [head, "|" + "---|" * (len(cols) + 3)]
    for n in ranking(results, comparison):
        t = results.timing.get(n, {})
        name = f"**{n}** (default)" if n == results.default else n
        cells = [_fmt(summary[n][c], c) for c in cols]
        timing = f"{t.get('cold_ms', math.nan):.1f} / {t.get('warm_ms', math.nan):.1f}"
        wins = f"{100 * win_rate(results, n, 'plate mean', comparison=comparison):.0f} %"
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {wins} | {timing} |")
    return "\n".join(lines)


def table_by(
    results: Results, by: str, metric: str = "mirror_psnr", comparison: str = "exr/hdr"
) -> str:
    groups = summarise(results, comparison, by=by)
    if by == "placement":
        keys = [p.name for p in PLACEMENTS if any(p.name in groups[m] for m in groups)]
    else:
        keys = sorted({g for m in groups for g in groups[m]})
    label = {"placement": "", "hfov": "°", "hdri": ""}[by]
    lines = [
        "| method | "
        + " | ".join(f"{k:g}{label}" if isinstance(k, float) else str(k) for k in keys)
        + " |",
        "|" + "---|" * (len(keys) + 1),
    ]
    for n in ranking(results, comparison):
        name = f"**{n}**" if n == results.default else n
        lines.append(
            f"| {name} | " + " | ".join(_fmt(groups[n][k][metric], metric) for k in keys) + " |"
        )
    return "\n".join(lines)


def table_targets(results: Results) -> str:
    lines = ["| target (default method) | comparison | measured | holds |", "|---|---|---|---|"]
    for comparison in [f"{p}/{t}" for p, t in (tuple(c) for c in results.config["comparisons"])]:
        for target, measured, holds in check_targets(results, comparison):
            lines.append(
                f"| {target} | {comparison} | {measured} | {'yes' if holds else '**no**'} |"
            )
    return "\n".join(lines)


def table_claims(results: Results) -> str:
    lines = [
        "| claim (checked by tests/study/test_evaluate.py on the quick subset) | holds here |",
        "|---|---|",
    ]
    for claim, holds in check_claims(results):
        lines.append(f"| {claim} | {'yes' if holds else '**no**'} |")
    return "\n".join(lines)


def table_auto(results: Results) -> str:
    auto = results.auto
    summ = auto_summary(auto)
    widths = [str(w) for w in auto["widths"]]
    cost = auto["width_cost"]
    lines = [
        "| object | auto width | " + " | ".join(f"{w}" for w in widths) + " |",
        "|" + "---|" * (len(widths) + 2),
        "| *cold ms per map* | | " + " | ".join(f"{cost[w]['cold_ms']:.0f}" for w in widths) + " |",
    ]
    for d, entry in summ["resolution"].items():
        best = max(entry["psnr"].values())
        for key, label in (
            ("psnr", "vs truth, minus best"),
            ("self_psnr", "vs own 2048 map"),
            ("truth_psnr", "true map vs 2048"),
        ):
            cells = []
            for w in widths:
                v = entry[key][w] - best if key == "psnr" else entry[key][w]
                text = f"{v:+.2f}" if key == "psnr" else (f"{v:.1f}" if v < 99 else "ref")
                cells.append(f"**{text}**" if int(w) == entry["auto_width"] else text)
            lines.append(
                f"| {d} px ({label}) | {entry['auto_width']} | " + " | ".join(cells) + " |"
            )
    lines += [
        "",
        "| light for rough / diffuse materials | PSNR (dB) | si-RMSE | cost (ms) |",
        "|---|---|---|---|",
    ]
    for n, v in summ["rough"].items():
        lines.append(
            f"| {n} | {v['psnr']:.2f} | {v['si_rmse']:.3f} | {auto['rough_cost_ms'][n]:.1f} |"
        )
    return "\n".join(lines)


def update_markdown(path, blocks: dict) -> bool:
    """Replace each `<!-- evaluate:NAME -->...<!-- /evaluate:NAME -->` block of the file at
    `path` with `blocks[NAME]`; returns whether the file existed (it is never created)."""
    path = pathlib.Path(path)
    if not path.is_file():
        return False
    text = path.read_text()
    for name, body in blocks.items():
        pattern = re.compile(
            rf"(<!-- evaluate:{re.escape(name)} -->\n).*?(<!-- /evaluate:"
            rf"{re.escape(name)} -->)",
            re.S,
        )
        text = pattern.sub(lambda m, b=body: m.group(1) + b.rstrip() + "\n" + m.group(2), text)
    path.write_text(text)
    return True
