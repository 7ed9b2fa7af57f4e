"""`python -m engine study`: what accuracy costs in time, for every knob.

Every row renders the built-in Cornell scene K times with different seeds and reports
wall time and error against a converged reference rendered once at high sample count:

* RMSE and relMSE = mean((I - R)^2 / (R^2 + 0.01)) (pbrt's MRSE form), mean and spread
  over the K runs;
* variance: per-pixel sample variance across the K runs, averaged over pixels;
* bias^2 = (mean of the K images - reference)^2 - variance / K - (the reference's own
  variance), averaged over pixels: the part more samples never remove (depth limits,
  Schlick against an exact-Fresnel reference), with its standard error over pixels;
* efficiency 1 / (MSE t) (pbrt-v3 §13.7), and the time to reach relMSE = target,
  t relMSE / target for unbiased rows (variance falls as 1/t), "never" when the
  relative bias^2 alone exceeds the target.

The tables follow the report's chapter 3 (Tables 3.1-3.4, §3.6), plus Schlick against
exact Fresnel, the estimators (the report's area sampling against solid-angle light sampling
and MIS, random numbers against Sobol' points) on four rooms, and an equal-time / equal-error
comparison against Cycles on the same .blend file and cores (when the bpy module and the
add-on are available).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..scene.builtin import cornell_scene, torus
from ..api import render
from ..core.paths import TRACER_DIR
from ..core.settings import RenderSettings

EPSILON_REL = 1e-2
REL_MSE_TARGET = 1e-2


@dataclass
class StudyMode:
    name: str
    resolution: tuple
    reference_spp: int
    base_spp: int
    runs: int                      # K independent seeds per row
    spp_sweep: tuple
    shadow_rays: tuple
    depths: tuple
    accel_resolution: tuple
    accel_spp: int
    triangle_sweep: tuple          # (rings, sides) of the torus for Embree vs octree
    cycles_spp: tuple
    cycles_reference_spp: int
    sheet_spp: tuple


QUICK = StudyMode("quick", (24, 24), 256, 4, 4, (1, 4, 16), (1, 4, 10), (0, 1, 2, 6), (12, 12), 1,
                  ((10, 10), (25, 20)), (), 0, (4, 16, 64, 128))
FULL = StudyMode("full", (64, 64), 2048, 16, 4, (1, 4, 16, 64, 256, 1024), (1, 4, 10, 20, 80),
                 (0, 1, 2, 6), (32, 32), 4, ((10, 10), (25, 20), (50, 50), (100, 100), (250, 200)),
                 (4, 16, 64), 1024, (50, 100, 600, 1000))


@dataclass
class Row:
    table: str
    label: str
    seconds: list = field(default_factory=list)
    mse: list = field(default_factory=list)
    rel_mse: list = field(default_factory=list)
    variance: float = 0.0
    rel_variance: float = 0.0
    bias2: float = 0.0
    rel_bias2: float = 0.0
    rel_bias2_se: float = 0.0
    extra: dict = field(default_factory=dict)
    image: np.ndarray | None = None

    @property
    def t(self):
        return float(np.mean(self.seconds))

    @property
    def mse_mean(self):
        return float(np.mean(self.mse))

    @property
    def rmse(self):
        return float(np.sqrt(self.mse_mean))

    @property
    def efficiency(self):
        return 1.0 / (self.mse_mean * self.t) if self.mse_mean > 0 and self.t > 0 else float("inf")

    def time_to_target(self, target=REL_MSE_TARGET):
        # "never" only when the bias is significant: its estimate less two standard
        # errors still exceeds half the target.
        if self.rel_bias2 - 2.0 * self.rel_bias2_se > 0.5 * target:
            return float("inf")
        return self.t * float(np.mean(self.rel_mse)) / target


def fresnel_bias(ref_schlick, ref_exact) -> dict:
    """Schlick's bias measured between the two converged references (noise removed)."""
    (rs, vs), (re, ve) = ref_schlick, ref_exact
    diff = rs - re
    noise = vs + ve
    z = np.abs(diff) / np.sqrt(noise + 1e-30)
    region = z.max(axis=2) > 4.0            # pixels where the two differ beyond noise
    return {"bias2": float((diff ** 2 - noise).mean()), "mean_diff": float(diff.mean()),
            "region_fraction": float(region.mean()),
            "region_rel_diff": float(diff[region].sum() / max(re[region].sum(), 1e-30)) if region.any() else 0.0}


def error_row(table, label, images, seconds, reference, reference_var, extra=None) -> Row:
    ref = reference
    weight = 1.0 / (ref ** 2 + EPSILON_REL)
    stack = np.stack(images)
    sq = (stack - ref) ** 2
    row = Row(table, label, list(seconds), [float(x) for x in sq.mean(axis=(1, 2, 3))],
              [float(x) for x in (sq * weight).mean(axis=(1, 2, 3))], extra=extra or {})
    var = stack.var(axis=0, ddof=1)
    row.variance = float(var.mean())
    row.rel_variance = float((var * weight).mean())
    # The mean of the K images has variance var / K: a far steadier bias estimate than
    # MSE - variance, which keeps the fireflies of every single run.
    bias2 = (stack.mean(axis=0) - ref) ** 2 - var / len(images) - reference_var
    row.bias2 = float(bias2.mean())
    rel = (bias2 * weight).ravel()
    row.rel_bias2 = float(rel.mean())
    row.rel_bias2_se = float(rel.std(ddof=1) / np.sqrt(rel.size))
    row.image = images[0]
    return row


class Study:
    def __init__(self, mode: StudyMode, out_dir: str, log=print):
        self.mode = mode
        self.out_dir = out_dir
        self.log = log
        self.rows: list[Row] = []
        self.notes: list[str] = []
        # 32-pixel tiles: four tiles at 64x64 keep both cores busy, each still big enough
        # (16k paths at 16 spp) that per-batch Python overhead stays small.
        self.base = RenderSettings(samples=mode.base_spp, shadow_rays=1, max_depth=8, threads=0, tile_size=32)

    def scene(self, with_mesh=True, resolution=None, torus_size=None):
        scene = cornell_scene(resolution or self.mode.resolution)
        if not with_mesh:
            scene.meshes = [m for m in scene.meshes if m.name != "Torus"]
        elif torus_size is not None:
            scene.meshes = [m for m in scene.meshes if m.name != "Torus"]
            rings, sides = torus_size
            scene.meshes.append(torus("Torus", (0.25, 0.45, 0.12), 0.3, 0.12, rings, sides, 6))
        return scene

    def runs(self, scene, settings, k=None):
        images, seconds, stats = [], [], None
        for i in range(k or self.mode.runs):
            result = render(scene, replace(settings, seed=1000 + i), log=lambda *a: None)
            images.append(result.image.astype(np.float64))
            seconds.append(result.stats["render_seconds"])
            stats = result.stats
        return images, seconds, stats

    def reference(self, scene, settings, label):
        t0 = time.perf_counter()
        result = render(scene, replace(settings, samples=self.mode.reference_spp, seed=7), log=lambda *a: None)
        self.log(f"reference {label}: {self.mode.reference_spp} spp in {time.perf_counter() - t0:.1f} s")
        return result.image.astype(np.float64), result.variance.astype(np.float64)

    def add(self, table, label, scene, settings, ref, k=None, extra=None):
        images, seconds, stats = self.runs(scene, settings, k)
        row = error_row(table, label, images, seconds, *ref, extra=extra)
        row.extra.setdefault("rays", sum(stats["rays"].values()))
        self.rows.append(row)
        self.log(f"  {table:10s} {label:28s} {row.t:8.3f} s  RMSE {row.rmse:.4g}  relMSE {np.mean(row.rel_mse):.3g}")
        return row

    # -- the tables -------------------------------------------------------------------
    def run(self):
        m = self.mode
        scene = self.scene()
        exact = replace(self.base, fresnel="exact")
        ref = self.reference(scene, self.base, "Schlick, depth 8")
        ref_exact = self.reference(scene, exact, "exact Fresnel, depth 8")
        self.fresnel_bias = fresnel_bias(ref, ref_exact)
        self.notes.append(f"References: {m.reference_spp} spp, max depth 8 with Russian roulette, seed 7.")

        for n in m.shadow_rays:                                   # Table 3.1
            self.add("3.1", f"{n} shadow rays", scene, replace(self.base, shadow_rays=n), ref,
                     extra={"shadow_rays": n})
        threads = sorted({1, os.cpu_count() or 1} | set(range(1, (os.cpu_count() or 1) + 1)))
        spp = 8 * m.base_spp         # a longer render, as the report's Table 3.3, so start-up is negligible
        for t in threads:                                          # Table 3.3
            self.add("3.3", f"{t} thread(s), {spp} spp", scene, replace(self.base, threads=t, samples=spp), ref,
                     extra={"threads": t})
        for depth in m.depths:                                     # Table 3.4
            self.add("3.4", f"depth {depth}", scene, replace(self.base, max_depth=depth), ref,
                     extra={"depth": depth})
        self.add("3.4", "depth 8, no Russian roulette", scene, replace(self.base, russian_roulette=False), ref,
                 extra={"depth": 8, "rr": False})
        for spp in m.spp_sweep:                                    # §3.6
            self.add("3.6", f"{spp} spp", scene, replace(self.base, samples=spp), ref, extra={"spp": spp})
        for fresnel in ("schlick", "exact"):                        # Schlick vs exact
            self.add("fresnel", f"{fresnel} (vs exact reference)", scene, replace(self.base, fresnel=fresnel),
                     ref_exact, extra={"fresnel": fresnel})
        self.denoise_table(scene, ref)
        self.accelerator_table()
        self.estimators_table()
        self.cycles_table()

    def denoise_table(self, scene, ref):
        """OIDN (engine/film/denoise.py) on a base-spp render, guided by its albedo and normal passes,
        against raw renders of base and 16x base spp; time = tracing + denoising."""
        from ..film.denoise import available, denoise_result
        problem = available()
        if problem:
            self.notes.append(f"Denoising rows skipped: {problem}")
            return
        base = self.mode.base_spp
        passes = replace(self.base, passes=("albedo", "normal"))
        for spp, denoised in ((base, False), (base, True), (16 * base, False)):
            images, seconds = [], []
            for i in range(self.mode.runs):
                result = render(scene, replace(passes, samples=spp, seed=1000 + i), log=lambda *a: None)
                t = result.stats["render_seconds"]
                if denoised:
                    denoise_result(result)
                    t += result.stats["denoise_seconds"]
                images.append(result.image.astype(np.float64))
                seconds.append(t)
            label = f"{spp} spp" + (" + OIDN denoise" if denoised else " raw")
            row = error_row("denoise", label, images, seconds, *ref, extra={"spp": spp, "denoised": denoised})
            self.rows.append(row)
            self.log(f"  denoise    {label:28s} {row.t:8.3f} s  RMSE {row.rmse:.4g}  relMSE {np.mean(row.rel_mse):.3g}")

    def estimators_table(self):
        """The report's estimator against solid-angle light sampling, MIS and the Sobol' sampler
        on the built-in rooms that stress light sampling (reference: mis, reference_spp)."""
        from ..scene.builtin import BUILTIN_SCENES
        variants = (("report, random numbers", "report", "random"), ("solid-angle", "solid-angle", "sobol"),
                    ("mis, random numbers", "mis", "random"), ("mis", "mis", "sobol"))
        for name in ("cornell", "near_lamp", "caustic", "many_lights"):
            scene = BUILTIN_SCENES[name](self.mode.resolution)
            ref = self.reference(scene, replace(self.base, estimator="mis"), f"estimators, {name}")
            for label, estimator, sampler in variants:
                self.add("estimators", f"{name}: {label}", scene,
                         replace(self.base, estimator=estimator, sampler=sampler), ref,
                         extra={"scene": name, "estimator": estimator, "sampler": sampler})

    def accelerator_table(self):                                   # Table 3.2
        m = self.mode
        settings = replace(self.base, samples=m.accel_spp)
        for with_mesh in (True, False):
            scene = self.scene(with_mesh, m.accel_resolution)
            ref = self.reference(scene, settings, f"accelerators, mesh={with_mesh}")
            for accel in ("embree", "octree", "brute"):
                n_tri = sum(len(x.triangles) for x in scene.meshes)
                self.add("3.2", f"{accel}, {'with' if with_mesh else 'no'} torus ({n_tri} tris)", scene,
                         replace(settings, accelerator=accel), ref, k=2,
                         extra={"accelerator": accel, "triangles": n_tri, "mesh": with_mesh})
        for size in m.triangle_sweep:
            scene = self.scene(True, m.accel_resolution, torus_size=size)
            n_tri = sum(len(x.triangles) for x in scene.meshes)
            ref = self.reference(scene, settings, f"torus {n_tri}")
            for accel in ("embree", "octree"):
                self.add("3.2b", f"{accel}, {n_tri} triangles", scene, replace(settings, accelerator=accel),
                         ref, k=2, extra={"accelerator": accel, "triangles": n_tri})

    def cycles_table(self):
        m = self.mode
        blend = os.path.join(os.path.dirname(TRACER_DIR), "sample_blends", "cornell.blend")
        if not m.cycles_spp:
            self.notes.append("Cycles comparison skipped in quick mode.")
            return
        if not os.path.exists(blend):
            self.notes.append(f"Cycles comparison skipped: {blend} not found.")
            return
        w, h = m.resolution

        def run(engine, spp, seed):
            with tempfile.TemporaryDirectory() as tmp:
                exr, stats = os.path.join(tmp, "o.exr"), os.path.join(tmp, "s.json")
                cmd = [sys.executable, "-m", "mcrt_addon", "render", blend, "-o", exr, "--engine", engine,
                       "--samples", str(spp), "--seed", str(seed), "--resolution", str(w), str(h),
                       "--max-depth", "8", "--fresnel", "exact", "--stats-json", stats]
                proc = subprocess.run(cmd, capture_output=True, text=True)
                if proc.returncode != 0:
                    raise RuntimeError(proc.stderr.strip().splitlines()[-1] if proc.stderr else "failed")
                from ..film.image_files import read_image
                return read_image(exr).astype(np.float64)[..., :3], json.load(open(stats))["render_seconds"]

        try:
            ref, _ = run("CYCLES", m.cycles_reference_spp, 99)
        except Exception as exc:  # no bpy module, or the add-on failed: say so in the doc
            self.notes.append(f"Cycles comparison skipped: {exc}")
            return
        zero = np.zeros_like(ref)
        for engine in ("CYCLES", "TNCG15_MC"):
            for spp in m.cycles_spp:
                images, seconds = zip(*[run(engine, spp, 200 + k) for k in range(m.runs)])
                row = error_row("cycles", f"{engine} {spp} spp", list(images), list(seconds), ref, zero,
                                extra={"engine": engine, "spp": spp})
                self.rows.append(row)
                self.log(f"  cycles     {row.label:28s} {row.t:8.3f} s  relMSE {np.mean(row.rel_mse):.3g}")
        self.notes.append(f"Cycles reference: {m.cycles_reference_spp} spp Cycles render of "
                          "sample_blends/cornell.blend; both engines exact Fresnel, max depth 8.")


def run_study(mode_name: str, out_dir: str, command: str, log=print) -> Study:
    from .report import plots, write_markdown
    mode = FULL if mode_name == "full" else QUICK
    fig_dir = os.path.join(out_dir, "accuracy")
    os.makedirs(fig_dir, exist_ok=True)
    start = time.perf_counter()
    study = Study(mode, out_dir, log=log)
    study.run()
    study.sheet_images = []
    for spp in mode.sheet_spp:
        result = render(study.scene(), replace(study.base, samples=spp, seed=3), log=lambda *a: None)
        study.sheet_images.append((spp, result.image))
    plots(study, fig_dir)
    seconds = time.perf_counter() - start
    write_markdown(study, os.path.join(out_dir, "accuracy-vs-time.md"), "accuracy", command, seconds)
    with open(os.path.join(fig_dir, "rows.json"), "w") as fh:
        json.dump([{"table": r.table, "label": r.label, "seconds": r.seconds, "mse": r.mse,
                    "rel_mse": r.rel_mse, "variance": r.variance, "bias2": r.bias2,
                    "rel_bias2": r.rel_bias2, "rel_bias2_se": r.rel_bias2_se, "extra": r.extra} for r in study.rows], fh, indent=1)
    log(f"study written to {out_dir} in {seconds:.0f} s")
    return study
