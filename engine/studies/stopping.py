"""`python -m engine study --stopping`: the study's rows for the stopping rules (docs/accuracy-stopping.md).

Two tables, each against a converged reference of the same scene (engine/studies/accuracy.py's relMSE,
mean((I - R)^2 / (R^2 + 0.01))):

* Calibration of the error estimate: K seeds at a few sample counts per scene; the estimated
  relative error E (engine/film/error_estimate.py, RMS over the seeds) against the actual one,
  sqrt(relMSE - the reference's own relMSE); target: ratio within 1 +- 25 %.
* Adaptive against uniform sampling on scenes with caustics and a near-field lamp:
  - equal error: both stop at the same noise target; the time each needs to reach the same actual
    relMSE is t relMSE / relMSE_target (variance falls as 1/t), so the time ratio at equal error
    is (t relMSE)_adaptive / (t relMSE)_uniform; target <= 0.7;
  - equal time: both get the same time limit; their actual relMSE.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace

import numpy as np

from ..scene.builtin import BUILTIN_SCENES
from ..api import render
from ..core.settings import RenderSettings

EPSILON_REL = 1e-2


@dataclass
class StoppingMode:
    name: str
    resolution: tuple
    reference_spp: int
    runs: int
    calibration_spp: tuple
    calibration_scenes: tuple
    adaptive_scenes: tuple          # (scene, noise target)


QUICK = StoppingMode("quick", (16, 16), 256, 2, (16,), ("cornell",), (("caustic", 0.15),))
FULL = StoppingMode("full", (64, 64), 4096, 4, (16, 64, 256), ("cornell", "near_lamp", "caustic"),
                    (("caustic", 0.08), ("near_lamp", 0.04)))


def rel_mse(image, ref):
    return float(np.mean((image - ref) ** 2 / (ref * ref + EPSILON_REL)))


class StoppingStudy:
    def __init__(self, mode: StoppingMode, log=print):
        self.mode, self.log = mode, log
        self.base = RenderSettings(samples=16, max_depth=8, tile_size=32)
        self.references = {}
        self.calibration_rows, self.adaptive_rows = [], []

    def scene(self, name):
        s = BUILTIN_SCENES[name]()
        s.resolution = self.mode.resolution
        return s

    def reference(self, name):
        if name not in self.references:
            t0 = time.perf_counter()
            r = render(self.scene(name), replace(self.base, samples=self.mode.reference_spp, seed=7),
                       log=lambda *a: None)
            ref = r.image.astype(np.float64)
            own = float(np.mean(r.variance / (ref * ref + EPSILON_REL)))     # the reference's own relMSE
            self.references[name] = (ref, own)
            self.log(f"reference {name}: {self.mode.reference_spp} spp in {time.perf_counter() - t0:.1f} s, "
                     f"own relative error {np.sqrt(own) * 100:.2f} %")
        return self.references[name]

    def render(self, name, settings):
        return render(self.scene(name), settings, log=lambda *a: None)

    def calibration(self):
        for name in self.mode.calibration_scenes:
            ref, own = self.reference(name)
            for spp in self.mode.calibration_spp:
                est, act = [], []
                for seed in range(self.mode.runs):
                    r = self.render(name, replace(self.base, samples=spp, seed=100 + seed, noise_target=1e-9,
                                                  adaptive=False))
                    est.append(r.stats["estimated_rel_error"])
                    act.append(max(rel_mse(r.image, ref) - own, 0.0))
                e, a = float(np.sqrt(np.mean(np.square(est)))), float(np.sqrt(np.mean(act)))
                row = {"scene": name, "spp": spp, "estimated": e, "actual": a, "ratio": e / a if a > 0 else float("nan"),
                       "per_seed_estimated": est, "per_seed_actual": [float(np.sqrt(x)) for x in act]}
                self.calibration_rows.append(row)
                self.log(f"  calibration {name:10s} {spp:5d} spp  est {e * 100:6.2f} %  actual {a * 100:6.2f} %  "
                         f"ratio {row['ratio']:.2f}")

    def runs(self, name, settings):
        ref, own = self.reference(name)
        out = {"seconds": [], "rel_mse": [], "spp": [], "estimated": []}
        for seed in range(self.mode.runs):
            r = self.render(name, replace(settings, seed=200 + seed))
            out["seconds"].append(r.stats["render_seconds"])
            out["rel_mse"].append(max(rel_mse(r.image, ref) - own, 1e-12))
            out["spp"].append(r.stats["samples_per_pixel"]["mean"])
            out["estimated"].append(r.stats["estimated_rel_error"])
        return {k: float(np.mean(v)) for k, v in out.items()}

    def adaptive(self):
        for name, target in self.mode.adaptive_scenes:
            rows = {}
            for label, adaptive in (("uniform", False), ("adaptive", True)):
                settings = replace(self.base, samples=8192, noise_target=target, adaptive=adaptive)
                rows[label] = self.runs(name, settings)
            u, a = rows["uniform"], rows["adaptive"]
            equal_error = (a["seconds"] * a["rel_mse"]) / (u["seconds"] * u["rel_mse"])
            limit = u["seconds"]
            timed = {}
            for label, adaptive in (("uniform", False), ("adaptive", True)):
                settings = replace(self.base, samples=1 << 20, noise_target=target / 4, adaptive=adaptive,
                                   time_limit=limit)
                timed[label] = self.runs(name, settings)
            row = {"scene": name, "target": target, "equal_error": rows, "time_ratio_at_equal_error": equal_error,
                   "equal_time": timed, "time_limit": limit,
                   "rel_mse_ratio_at_equal_time": timed["adaptive"]["rel_mse"] / timed["uniform"]["rel_mse"]}
            self.adaptive_rows.append(row)
            self.log(f"  adaptive {name:10s} target {target}: uniform {u['seconds']:.2f} s relMSE {u['rel_mse']:.3g}, "
                     f"adaptive {a['seconds']:.2f} s relMSE {a['rel_mse']:.3g}: time ratio at equal error "
                     f"{equal_error:.2f}; equal time {limit:.1f} s: relMSE ratio {row['rel_mse_ratio_at_equal_time']:.2f}")

    def markdown(self, command, seconds) -> str:
        m = self.mode
        out = ["# Stopping rules: the error estimate and adaptive sampling", "",
               f"Generated by `{command}` ({m.name} mode, {m.resolution[0]}x{m.resolution[1]}, {m.runs} seeds per "
               f"row, references {m.reference_spp} spp seed 7, {seconds:.0f} s; load average when it started: "
               f"{self.load}). Definitions: docs/user-guide.md, *Stopping rules*; code: engine/studies/stopping.py.", "",
               "## Calibration of the estimated relative error", "",
               "E = sqrt(mean over pixels and channels of Var / (R^2 + 0.01)); estimated from the two half "
               "buffers of each render, actual from the render against the reference (the reference's own "
               "relMSE subtracted). Both RMS over the seeds. Target: ratio 0.75-1.25.", "",
               "| scene | spp | estimated E | actual E | ratio |", "|---|---:|---:|---:|---:|"]
        for r in self.calibration_rows:
            out.append(f"| {r['scene']} | {r['spp']} | {r['estimated'] * 100:.2f} % | {r['actual'] * 100:.2f} % | "
                       f"{r['ratio']:.2f} |")
        out += ["", "## Adaptive against uniform sampling", "",
                "Equal error: both renders stop at the noise target (cap 8192 spp); the time to reach a common "
                "relMSE is t relMSE / relMSE_target, so the ratio of t relMSE is the time ratio at equal error "
                "(target <= 0.7). Equal time: both get the uniform render's time as their time limit.", "",
                "| scene | noise target | sampling | mean spp | seconds | est. E | actual relMSE | t relMSE | "
                "time ratio at equal error |", "|---|---:|---|---:|---:|---:|---:|---:|---:|"]
        for r in self.adaptive_rows:
            for label in ("uniform", "adaptive"):
                x = r["equal_error"][label]
                ratio = f"{r['time_ratio_at_equal_error']:.2f}" if label == "adaptive" else "1"
                out.append(f"| {r['scene']} | {r['target']} | {label} | {x['spp']:.0f} | {x['seconds']:.2f} | "
                           f"{x['estimated'] * 100:.2f} % | {x['rel_mse']:.3g} | {x['seconds'] * x['rel_mse']:.3g} | "
                           f"{ratio} |")
        out += ["", "| scene | time limit | sampling | mean spp | seconds | actual relMSE | relMSE ratio |",
                "|---|---:|---|---:|---:|---:|---:|"]
        for r in self.adaptive_rows:
            for label in ("uniform", "adaptive"):
                x = r["equal_time"][label]
                ratio = f"{r['rel_mse_ratio_at_equal_time']:.2f}" if label == "adaptive" else "1"
                out.append(f"| {r['scene']} | {r['time_limit']:.1f} s | {label} | {x['spp']:.0f} | {x['seconds']:.2f} | "
                           f"{x['rel_mse']:.3g} | {ratio} |")
        return "\n".join(out) + "\n"


def run_stopping_study(mode_name: str, out_dir: str, command: str, log=print) -> StoppingStudy:
    import json
    study = StoppingStudy(FULL if mode_name == "full" else QUICK, log=log)
    study.load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    start = time.perf_counter()
    study.calibration()
    study.adaptive()
    seconds = time.perf_counter() - start
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "accuracy-stopping.md"), "w") as fh:
        fh.write(study.markdown(command, seconds))
    with open(os.path.join(out_dir, "accuracy-stopping.json"), "w") as fh:
        json.dump({"calibration": study.calibration_rows, "adaptive": study.adaptive_rows}, fh, indent=1)
    log(f"stopping study written to {out_dir}/accuracy-stopping.md in {seconds:.0f} s")
    return study
