"""Shader nodes: the programs of engine/scene/programs.py run over a wavefront of hits
(engine/nodes/evaluator.py), one kernel per Blender node type (engine/nodes/registry.py), the hit
attributes they read (engine/nodes/context.py).  docs/nodes.md lists the nodes and their cost."""
