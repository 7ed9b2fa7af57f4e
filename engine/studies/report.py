"""Tables, plots and contact sheets for `python -m engine study`."""
from __future__ import annotations

import datetime
import os
import platform

import numpy as np

from ..film.image_files import linear_to_srgb

TABLE_TITLES = {
    "3.1": "Table 3.1 — shadow rays per diffuse hit",
    "3.2": "Table 3.2 — accelerators, with and without the 5,000-triangle torus",
    "3.2b": "Table 3.2b — Embree against the octree as the triangle count grows",
    "3.3": "Table 3.3 — threads",
    "3.4": "Table 3.4 — recursion depth and Russian roulette",
    "3.6": "§3.6 — samples per pixel",
    "fresnel": "Schlick against exact Fresnel (reference: exact Fresnel)",
    "estimators": "Estimators — the report's area sampling against solid-angle light sampling and MIS",
    "cycles": "Against Cycles on sample_blends/cornell.blend (reference: Cycles, high spp)",
    "denoise": "Denoising — OIDN on a low-spp render against a raw render of 16× the samples",
}


def fmt_time(t):
    return "never" if not np.isfinite(t) else (f"{t:.3g} s" if t < 100 else f"{t / 60:.1f} min")


def markdown_table(rows):
    lines = ["| setting | time (s) | RMSE | relMSE | variance | bias² | efficiency 1/(MSE·t) | time to relMSE 1e-2 |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r.label} | {r.t:.3f} ± {np.std(r.seconds):.3f} | {r.rmse:.4g} | "
            f"{np.mean(r.rel_mse):.3g} ± {np.std(r.rel_mse):.2g} | {r.variance:.3g} | {r.bias2:.3g} | "
            f"{r.efficiency:.3g} | {fmt_time(r.time_to_target())} |")
    return "\n".join(lines)


def spp_slope(rows):
    spp = np.array([r.extra["spp"] for r in rows], float)
    rmse = np.array([r.rmse for r in rows])
    return float(np.polyfit(np.log(spp), np.log(rmse), 1)[0]) if len(rows) >= 2 else float("nan")


def contact_sheet(path, images, labels, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(images), figsize=(3 * len(images), 3.4))
    for ax, img, label in zip(np.atleast_1d(axes), images, labels):
        ax.imshow(linear_to_srgb(img), interpolation="nearest")
        ax.set_title(label, fontsize=9)
        ax.axis("off")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _figure():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt.subplots(figsize=(6, 4.2))


def _save(fig, ax, path, title, xlabel, ylabel, legend=True):
    import matplotlib.pyplot as plt
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if legend:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plots(study, fig_dir):
    rows = study.rows
    by = lambda table: [r for r in rows if r.table == table]
    files = {}
    spp_rows, sr = by("3.6"), by("3.1")
    t = np.array([r.t for r in spp_rows])
    e = np.array([r.rmse for r in spp_rows])

    fig, ax = _figure()
    ax.loglog(t, e, "o-", label="TNCG15 MC, spp sweep")
    ax.loglog([r.t for r in sr], [r.rmse for r in sr], "s--", label="shadow-ray sweep")
    for engine, style in (("CYCLES", "^-"), ("TNCG15_MC", "v-")):
        cr = [r for r in by("cycles") if r.extra["engine"] == engine]
        if cr:
            ax.loglog([r.t for r in cr], [r.rmse for r in cr], style, label=f"{engine} vs Cycles reference")
    if len(t):
        ax.loglog(t, e[0] * np.sqrt(t[0] / t), "k:", label="1/√t")
    files["error_vs_time"] = _save(fig, ax, os.path.join(fig_dir, "error-vs-time.png"), "Error against time",
                                   "render time (s)", "RMSE against reference")

    fig, ax = _figure()
    spp = np.array([r.extra["spp"] for r in spp_rows], float)
    ax.loglog(spp, e, "o-", label=f"RMSE (fitted slope {spp_slope(spp_rows):.3f})")
    if len(spp):
        ax.loglog(spp, e[0] * np.sqrt(spp[0] / spp), "k:", label="slope −0.5")
    files["error_vs_spp"] = _save(fig, ax, os.path.join(fig_dir, "error-vs-spp.png"),
                                  "Error against samples per pixel", "samples per pixel", "RMSE")

    fig, ax = _figure()
    ax.semilogx([r.extra["shadow_rays"] for r in sr], [r.efficiency for r in sr], "o-")
    files["efficiency"] = _save(fig, ax, os.path.join(fig_dir, "efficiency-vs-shadow-rays.png"),
                                "Efficiency against shadow rays", "shadow rays per diffuse hit",
                                "efficiency 1/(MSE·t)", legend=False)

    fig, ax = _figure()
    for accel in ("embree", "octree"):
        ar = [r for r in by("3.2b") if r.extra["accelerator"] == accel]
        ax.loglog([r.extra["triangles"] for r in ar], [r.t for r in ar], "o-", label=accel)
    files["accel"] = _save(fig, ax, os.path.join(fig_dir, "accelerator-time-vs-triangles.png"),
                           "Embree against the octree", "triangles in the scene", "render time (s)")

    contact_sheet(os.path.join(fig_dir, "fig-3-1-shadow-rays.png"), [r.image for r in sr],
                  [r.label for r in sr], "Shadow rays (cf. report Figure 3.1)")
    dr = [r for r in by("3.4") if r.extra.get("rr", True)]
    contact_sheet(os.path.join(fig_dir, "fig-3-2-depth.png"), [r.image for r in dr],
                  [r.label for r in dr], "Recursion depth (cf. report Figure 3.2)")
    sheet = study.sheet_images
    contact_sheet(os.path.join(fig_dir, "fig-3-4-spp.png"), [img for _, img in sheet],
                  [f"{spp} spp" for spp, _ in sheet], "Samples per pixel (cf. report Figure 3.4)")
    files["sheets"] = ["fig-3-1-shadow-rays.png", "fig-3-2-depth.png", "fig-3-4-spp.png"]
    return files


def write_markdown(study, path, fig_rel, command, seconds):
    m = study.mode
    rows = study.rows
    by = lambda table: [r for r in rows if r.table == table]
    out = [
        "# What accuracy costs in time",
        "",
        f"Generated by `{command}` ({m.name} mode) on {datetime.date.today().isoformat()}, "
        f"{platform.machine()} with {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"in {seconds / 60:.1f} minutes.",
        "",
        f"Scene: the built-in Cornell room (report Figure 3.5) at {m.resolution[0]}×{m.resolution[1]}, "
        f"{m.base_spp} spp, 1 shadow ray, max depth 8 with Russian roulette unless a row says otherwise. "
        f"Every row is {m.runs} renders with different seeds (Table 3.2: 2 renders at "
        f"{m.accel_resolution[0]}×{m.accel_resolution[1]}, {m.accel_spp} spp); time is tracing only, mean ± sd.",
        "",
        "Columns: RMSE and relMSE = mean((I − R)²/(R² + 0.01)) against the reference R; variance = per-pixel "
        "variance across the runs, averaged; bias² = (mean of the runs − reference)² − variance/runs − the reference's own variance (≈ 0 for "
        "unbiased settings, up to noise); efficiency = 1/(MSE·t); time to relMSE 1e-2 = t·relMSE/1e-2 "
        "(variance falls as 1/t), or *never* when the bias alone exceeds it.",
        "",
    ]
    out += [f"- {n}" for n in study.notes] + [""]
    out += ["The stopping rules (noise target, time limit, adaptive against uniform sampling at equal time and equal error, the calibration of the error estimate) have their own rows: [accuracy-stopping.md](accuracy-stopping.md) (`python -m engine study --stopping --full`).", ""]
    for table in ("3.1", "3.2", "3.2b", "3.3", "3.4", "3.6", "fresnel", "denoise", "estimators", "cycles"):
        rs = by(table)
        if not rs:
            continue
        out += [f"## {TABLE_TITLES[table]}", "", markdown_table(rs), ""]
        if table == "3.6":
            out += [f"Fitted slope of log RMSE against log spp: **{spp_slope(rs):.3f}** (−0.5 expected for "
                    "independent samples).", ""]
        if table == "3.3" and len(rs) > 1:
            out += [f"Speed-up 1 → {rs[-1].extra['threads']} threads: **{rs[0].t / rs[-1].t:.2f}×**.", ""]
        if table == "cycles":
            out += cycles_summary(rs) + [""]
        if table == "denoise":
            out += denoise_summary(rs) + [""]
        if table == "estimators":
            out += estimators_summary(rs, os.path.join(os.path.dirname(path), "estimators.json")) + [""]
        if table == "fresnel" and getattr(study, "fresnel_bias", None):
            fb = study.fresnel_bias
            out += [f"Between the two converged references ({m.reference_spp} spp each): bias² of Schlick = "
                    f"{fb['bias2']:.3g} over the whole image (image-mean difference {fb['mean_diff']:+.3g}); "
                    f"{fb['region_fraction'] * 100:.1f} % of the pixels differ beyond 4σ, and there Schlick is "
                    f"{fb['region_rel_diff'] * 100:+.1f} % off (relative). Both models cost the same time.", ""]
    out += ["## Plots", ""]
    for name in ("error-vs-time.png", "error-vs-spp.png", "efficiency-vs-shadow-rays.png",
                 "accelerator-time-vs-triangles.png", "fig-3-1-shadow-rays.png", "fig-3-2-depth.png",
                 "fig-3-4-spp.png"):
        out.append(f"![{name}]({fig_rel}/{name})")
        out.append("")
    with open(path, "w") as fh:
        fh.write("\n".join(out))


def denoise_summary(rows):
    """One line: the denoised low-spp row against the raw high-spp row (relMSE and time ratios)."""
    den = next((r for r in rows if r.extra.get("denoised")), None)
    high = max((r for r in rows if not r.extra.get("denoised")), key=lambda r: r.extra["spp"], default=None)
    if den is None or high is None:
        return []
    return [f"{den.label}: relMSE {np.mean(den.rel_mse):.3g} in {den.t:.3f} s against {high.label}: relMSE "
            f"{np.mean(high.rel_mse):.3g} in {high.t:.3f} s, i.e. **{np.mean(den.rel_mse) / np.mean(high.rel_mse):.2f}×** "
            f"the error in **{den.t / high.t:.2f}×** the time; RMSE {den.rmse:.4g} against {high.rmse:.4g}. "
            "The denoised image is biased (bias² column): its error does not fall with more time the way "
            "the raw rows' does (relMSE weights dark pixels, RMSE bright ones: the lamp's edges)."]


def cycles_summary(rows):
    lines = []
    curves = {}
    for engine in ("CYCLES", "TNCG15_MC"):
        rs = sorted([r for r in rows if r.extra["engine"] == engine], key=lambda r: r.t)
        if rs:
            curves[engine] = (np.log([r.t for r in rs]), np.log([np.mean(r.rel_mse) for r in rs]), rs)
    if len(curves) == 2:
        (tc, ec, _), (to, eo, _) = curves["CYCLES"], curves["TNCG15_MC"]
        lo, hi = max(tc[0], to[0]), min(tc[-1], to[-1])
        if lo <= hi:
            t_mid = 0.5 * (lo + hi)
            e_c, e_o = np.exp(np.interp(t_mid, tc, ec)), np.exp(np.interp(t_mid, to, eo))
            lines.append(f"Equal time ({np.exp(t_mid):.2f} s): relMSE Cycles {e_c:.3g}, TNCG15 MC {e_o:.3g} "
                         f"(ratio {e_o / e_c:.2f}).")
        # Equal error at the lowest relMSE both engines reached; time by log-log interpolation.
        target = max(np.exp(ec).min(), np.exp(eo).min())
        t_c = np.exp(np.interp(np.log(target), ec[::-1], tc[::-1]))
        t_o = np.exp(np.interp(np.log(target), eo[::-1], to[::-1]))
        lines.append(f"Equal error (relMSE {target:.3g}): Cycles needs {fmt_time(t_c)}, TNCG15 MC "
                     f"{fmt_time(t_o)} (ratio {t_o / t_c:.2f}×), interpolated between the measured rows.")
    return lines


def estimators_summary(rows, bench_json):
    """Efficiency of each estimator against the report's on the same scene, and the measured
    comparison with Cycles from `make bench-estimators` (docs/estimators.json) when present."""
    lines = ["Scenes: `engine/scene/builtin.py` (`near_lamp`: the lamp hangs 2 cm under a closed ceiling; "
             "`caustic`: a glass ball on the floor under a small lamp; `many_lights`: 36 lamps of 8 cm, 1 cm under "
             "the ceiling). Reference: `mis` at the reference sample count. Efficiency gain over the report's "
             "estimator (random numbers) on the same scene:", ""]
    for scene in dict.fromkeys(r.extra["scene"] for r in rows):
        rs = [r for r in rows if r.extra["scene"] == scene]
        base = next(r for r in rs if r.extra["estimator"] == "report")
        gains = ", ".join(f"{r.label.split(': ', 1)[1]} {r.efficiency / base.efficiency:.3g}×" for r in rs
                          if r is not base)
        lines.append(f"- {scene}: {gains}")
    if os.path.exists(bench_json):
        import json
        with open(bench_json) as fh:
            bench = json.load(fh)
        st = bench.get("settings", {})
        lines += ["", "### Against Cycles (`make bench-estimators`, same machine, same threads)", "",
                  f"Blender's sample scenes at {'×'.join(map(str, st.get('resolution', [])))}, "
                  f"{st.get('samples')} spp, max depth "
                  f"{st.get('max_depth')}, {st.get('repeats')} seed(s) per row; reference: Cycles at "
                  f"{st.get('reference_samples')} spp. Written {bench.get('machine', {}).get('date', '')}.", "",
                  bench["table"]]
    return lines
