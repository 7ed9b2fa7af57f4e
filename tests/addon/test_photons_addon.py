"""Caustic photons through Blender (bpy 5.0 in-process): F12 with the add-on's render worker
processes, and the Rendered viewport (its workers follow the scene's Light Paths > Caustics
setting), each photon batch traced once and shared (engine/rendering/photon_passes.py).  Blender
3.4 from the legacy zip: tests/addon/test_photons_blender34.py."""
import time

import bpy
import numpy as np
import pytest

from mcrt_addon import bridge
from rendering import export_blend, last_report, render_operator

pytestmark = pytest.mark.slow        # worker processes start: 3-10 s each


@pytest.fixture
def caustic(addon, make_samples_module, tmp_path):
    path = make_samples_module.make("caustic", str(tmp_path), resolution=(32, 24))
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    scene.render.engine = "TNCG15_MC"
    p = scene.tncg15
    p.caustics_method, p.samples, p.photons_per_pass, p.seed = "PHOTONS", 12, 3000, 5
    return path, scene


def test_f12_renders_photon_caustics_on_its_workers(caustic):
    path, scene = caustic
    img = render_operator(scene)
    report = last_report()
    assert report.error is None, report.error
    st = report.stats
    assert "worker process" in st["parallelism"] and st["effects"]["photon_caustics"], st["parallelism"]
    ph = st["photons"]
    assert ph["distribution"] == "shared" and ph["photon_passes_traced"] == 16 and ph["photon_units"] == 2, ph
    # the tracer's own render of the exported file with the same settings: the same image
    settings = scene.tncg15.to_settings(bridge.settings_class())
    settings.threads = 1
    ref = bridge.render_function()(export_blend(path, (32, 24)).scene, settings, log=lambda *a: None).image
    np.testing.assert_allclose(img, ref, rtol=1e-5, atol=1e-6)
    assert img.mean() > 0.02


def test_the_rendered_viewport_follows_the_caustics_setting(caustic):
    from mcrt_addon import viewport
    from tests.addon.test_viewport import Handler, edit, stub_context, stub_engine
    _, scene = caustic
    scene.tncg15.viewport_samples = 4
    engine = stub_engine()
    ctx = stub_context(scene, 32, 24)
    bpy.context.view_layer.update()
    viewport.view_update(engine, ctx, bpy.context.evaluated_depsgraph_get())
    st = engine.viewport_state
    try:
        assert st.message is None, st.message
        deadline = time.perf_counter() + 120
        while not st.workers.converged() and time.perf_counter() < deadline:
            time.sleep(0.05)
        frame = st.workers.frame
        assert st.workers.converged() and frame.plan.enabled["photon_caustics"]
        assert frame.photon_schedule is not None and frame.photon_schedule.photon_units == 1
        assert frame.totals.photons["photon_passes_traced"] == 8          # once, for the viewport's two workers
        _, rgba, samples, *_ = st.workers.snapshot()
        assert samples == 4 and rgba[..., :3].mean() > 0.02
        with Handler(lambda dg: viewport.view_update(engine, ctx, dg)):  # the toggle: path tracing alone
            edit(lambda: (setattr(scene.tncg15, "caustics_method", "PATH"), scene.update_tag()))
        assert st.exports == 2
        deadline = time.perf_counter() + 120
        while not st.workers.converged() and time.perf_counter() < deadline:
            time.sleep(0.05)
        assert not st.workers.frame.plan.enabled["photon_caustics"] and not st.workers.frame.totals.photons
    finally:
        viewport.free(engine)
