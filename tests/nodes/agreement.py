"""The Cycles 5.0 agreement method of the node tests (tests/addon/rendering.py, tests/addon/imagecompare.py:
64 x 64, 32 spp, max depth 8, K = 4 seeds each), shared by the node agreement tests (tests/nodes/test_agreement_nodes.py and its siblings)."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "addon"))

TAU = 0.02      # the comparison's allowance beyond the noise (relative)


def against_cycles(path, name):
    """(the exported scene of the .blend at `path`, Cycles 5.0's K renders of it, cached as `name`)."""
    from rendering import RES, cycles_reference, export_blend
    return export_blend(path, RES), cycles_reference(path, name)


def saved(tmp_path_factory, name):
    """The open bpy file saved as `name`.blend in a fresh temporary directory (its path)."""
    import bpy
    path = str(tmp_path_factory.mktemp("nodes") / f"{name}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path


def compared(scene, reference, label, first_seed=None, png=None):
    """compare_runs of TNCG15 MC's K renders of `scene` against `reference`, its summary printed
    under `label`; `png`: also write ours and Cycles' means to /tmp/<png>_ours.png, _cycles.png."""
    from imagecompare import compare_runs
    from rendering import tncg15_agreement_runs, to_png
    ours = tncg15_agreement_runs(scene) if first_seed is None else tncg15_agreement_runs(scene, first_seed=first_seed)
    if png:
        to_png(ours.mean(0), f"/tmp/{png}_ours.png", 4)
        to_png(reference.mean(0), f"/tmp/{png}_cycles.png", 4)
    result = compare_runs(ours, reference, tau=TAU)
    print(f"{label}: {result.summary()}")
    return result
