# Everything runs from .venv at the repository root, made from requirements.txt.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
BLENDER ?= blender

.PHONY: setup render test test-slow test-all bench bench-primitives bench-animation bench-backend bench-speed bench-caustics bench-estimators bench-materials bench-files study extension samples clean

setup: $(STAMP)

$(STAMP): requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	touch $(STAMP)

# The sample Cornell .blend rendered by Blender (the bpy module) with the TNCG15 MC engine.
render: $(STAMP)
	$(PY) -m mcrt_addon render sample_blends/cornell.blend -o renders/cornell.exr --png renders/cornell.png \
	    --samples 64 --resolution 256 256 --caustics-method auto

test: $(STAMP)
	$(PY) -m pytest -q -m "not slow" tests

# Tests marked slow (kept out of `make test` so it stays under about 5 minutes); .ci/run runs both.
test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow tests

test-all: $(STAMP)
	$(PY) -m pytest -q tests

bench: $(STAMP)
	$(PY) -m engine bench
	$(PY) -m mcrt_addon bench-export
	$(PY) scripts/bench_primitives.py

# 10,000 spheres, quads, Area lights and round lamps against their triangle / point-light twins:
# time ratios measured in one run (docs/performance.md "Many primitives").
bench-primitives: $(STAMP)
	$(PY) scripts/bench_primitives.py

# An animation's frames with Persistent Data off and on, against their tracing time and Cycles (Blender 3.4 -a):
# docs/performance.md "Animation and Persistent Data".
bench-animation: $(STAMP)
	$(PY) scripts/bench_animation.py

# NumPy against numba's compiled kernels: per kernel on captured inputs, per render, compile cold and
# from the cache (docs/performance.md "Compiled kernels").
bench-backend: $(STAMP)
	$(PY) scripts/bench_backend.py

# ms/spp against the Embree-alone replay of the same rays, the per-stage table and 1 -> 2 workers, per
# scene (docs/performance.md "Speed"); BASELINE=<another checkout> adds its before / after ratios.
bench-speed: $(STAMP)
	$(PY) scripts/replay_embree.py --wavefronts 16384 32768 65536 131072 $(if $(BASELINE),--baseline $(BASELINE))

# Caustics: the photon map against path tracing at equal time on the caustic room (relMSE ratios).
bench-caustics: $(STAMP)
	$(PY) scripts/bench_caustics.py

# Light-sampling estimators (report | solid-angle | mis) vs Cycles on the light-sampling stress scenes:
# markdown table + docs/estimators.json; Cycles references cached in renders/reference/.
bench-estimators: $(STAMP)
	$(PY) -m mcrt_addon bench-estimators --out docs/estimators.json

# The material sample scenes vs Cycles (docs/materials.md, "Efficiency against Cycles"): markdown table +
# docs/materials-efficiency.json; Cycles references cached in renders/reference/.
bench-materials: $(STAMP)
	$(PY) -m mcrt_addon bench-materials --out docs/materials-efficiency.json

# Every sample_blends/*.blend against Cycles at 96^2 and 256^2, 2 threads: per-sample time (target <= 0.6x
# Cycles') and efficiency 1/(MSE t) (target >= 2x) (docs/performance.md "Against Cycles per sample file");
# Cycles references cached in renders/reference-files/, JSON in renders/.  FILES="cornell caustic" for some.
bench-files: $(STAMP)
	$(PY) scripts/bench_sample_files.py $(if $(FILES),--files $(FILES))

study: $(STAMP)
	$(PY) -m engine study --full

extension: $(STAMP)
	$(PY) scripts/build_extension.py

# The sample .blend files, saved by a Blender 3.4 binary (Debian's `blender`; BLENDER=... for
# another) so that 3.4 and every newer Blender open them, with TNCG15 MC as their render engine.
samples:
	$(BLENDER) -b --factory-startup --python-exit-code 1 --python sample_blends/make_samples.py --

clean:
	rm -rf renders .pytest_cache
