"""The cost of shader nodes (docs/nodes.md): `python scripts/bench_nodes.py eval` times each kernel of
engine/nodes/registry.py over a wavefront of N hits (ms per million hits); `python scripts/bench_nodes.py
export` (bpy) times the exporter's compile of a graph of one node of each kind (ms per node)."""
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
N = 1 << 18


def hit_context(n, rng):
    from engine.nodes.context import NodeContext

    def rows():
        return rng.normal(size=(3, n))

    def unit():
        v = rows()
        return v / np.linalg.norm(v, axis=0)

    class Images:
        pixels = rng.random((256, 256, 4)).astype(np.float32)

        def sample(self, texture, u, v, interpolation, extension, alpha):
            from engine.materials.textures import lookup
            values = lookup(self.pixels, u, v, interpolation, extension)
            return values[:, :3].T, values[:, 3]
    attrs = {name: rows() for name in ("position", "object", "generated", "uv", "camera", "object_location")}
    attrs.update({name: unit() for name in ("normal", "true_normal", "incoming", "object_normal")})
    attrs.update(backfacing=np.zeros(n), object_random=rng.random(n), ray_kind=np.zeros(n, np.int64),
                 ray_depth=np.zeros(n), ray_length=rng.random(n))
    return NodeContext(n, (5, 0), attrs, Images())


def bench_eval():
    from engine.nodes.registry import kernels
    rng = np.random.default_rng(1)
    ctx = hit_context(N, rng)
    vector = {"Vector": rng.random((3, N)), "Color": rng.random((3, N)), "Strength": rng.random(N)}
    rows = []
    for kind, kernel in sorted(kernels().items()):
        best = None
        for _ in range(3):
            t = time.perf_counter()
            try:
                kernel(dict(vector), {"texture": 0}, ctx)
            except Exception as exc:                      # a kernel that needs other inputs
                best = f"({type(exc).__name__})"
                break
            dt = time.perf_counter() - t
            best = dt if best is None else min(best, dt)
        rows.append((kind, best if isinstance(best, str) else f"{best / N * 1e9:.0f}"))
    print("| node | ms per million hits |\n|---|---|")
    for kind, ms in rows:
        print(f"| `{kind}` | {ms} |")


def bench_export():
    import bpy
    from mcrt_addon import bridge
    from mcrt_addon.export.images import ImageTable
    from mcrt_addon.export.materials import MaterialTable
    from mcrt_addon.export.node_graph import GraphCompiler
    warnings = []
    table = MaterialTable(bridge.scene_module(), warnings, ImageTable(bridge.module("scene.textures"), warnings))
    compiler = GraphCompiler(table, bridge.module("scene.programs"), bridge.module("nodes.evaluator"),
                             bridge.module("nodes.registry"))
    print("| node | export ms per node |\n|---|---|")
    for kind in sorted(compiler.kernels):
        if not kind.startswith("ShaderNode"):
            continue
        mat = bpy.data.materials.new(kind)
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        bsdf = nodes.get("Principled BSDF") or nodes.new("ShaderNodeBsdfPrincipled")
        geo = nodes.new("ShaderNodeNewGeometry")
        node = nodes.new(kind)
        if kind == "ShaderNodeTexImage":
            node.image = bpy.data.images.new("I", 4, 4)
        vec = next((s for s in node.inputs if s.type == "VECTOR"), None)
        if vec is not None:
            links.new(geo.outputs["Position"], vec)
        out = next((s for s in node.outputs if s.enabled and s.type != "SHADER"), None)
        if out is None:
            continue
        links.new(out, bsdf.inputs["Base Color"])
        reps = 50
        t = time.perf_counter()
        for _ in range(reps):
            compiler.compile(mat, bsdf, bsdf.inputs["Base Color"], "RGBA")
        print(f"| `{kind}` | {(time.perf_counter() - t) / reps * 1e3:.2f} |")


if __name__ == "__main__":
    bench_export() if sys.argv[1:] == ["export"] else bench_eval()
