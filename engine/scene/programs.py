"""Shader-node programs in the scene model: the node graph feeding one material input, compiled by the
exporter (mcrt_addon/export/node_graph.py) and run per hit by engine/nodes/evaluator.py.

A `Program` is its nodes in topological order (`ProgramNode`: the Blender node type, its name for
messages, its own properties as plain data, its inputs) and the output that feeds the material input.
An input is a constant (a float, or 3 floats for a colour or vector: a colour's alpha is dropped) or a
`Link` to an earlier node's output, with the socket types at both ends (Blender's socket types:
"VALUE", "RGBA", "VECTOR", "INT", "BOOLEAN"), so that the evaluator converts as Cycles does (colour to
float: luminance; vector to float: the average; float to colour or vector: grey).

Scene files (engine/scene/files.py) keep a material's programs under "programs":

    "programs": {"color": {"type": "RGBA", "output": [2, "Color", "RGBA"], "uv_maps": [""],
                           "nodes": [{"type": "ShaderNodeTexCoord", "name": "Texture Coordinate",
                                      "props": {}, "inputs": {}},
                                     {"type": "ShaderNodeMapping", "name": "Mapping",
                                      "props": {"vector_type": "POINT"},
                                      "inputs": {"Vector": {"link": [0, "Object", "VECTOR", "VECTOR"]},
                                                 "Scale": {"value": [2, 2, 2]}}}, ...]}}

A material's program roles (Material.programs keys): PROGRAM_ROLES.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..core.errors import SceneError

SOCKET_TYPES = ("VALUE", "RGBA", "VECTOR", "INT", "BOOLEAN")
# The material inputs a program may drive: the colour (Base Color / Color), the emitted radiance
# (colour x strength) and the float inputs of engine/scene/model.py TEXTURED_INPUTS.
COLOR_ROLES = ("color", "emission")
# The shading normal (a BSDF's Normal input: Normal Map, Bump, ...): rows (3, N), world space, on the
# viewer's side; it replaces the hit's shading normal (engine/integrators/path_tracer.py).
NORMAL_ROLE = "normal"


@dataclass(frozen=True)
class Link:
    """An input fed by output `output` (a Blender socket identifier) of node `node` (an index into
    Program.nodes, before the node that reads it); `source` and `target`: the socket types."""
    node: int
    output: str
    source: str = "RGBA"
    target: str = "RGBA"


@dataclass
class ProgramNode:
    kind: str                                   # the Blender node type (bl_idname)
    name: str = ""                              # the node's name, for messages
    props: dict = field(default_factory=dict)   # the node's own properties, plain data
    inputs: dict = field(default_factory=dict)  # socket identifier -> constant or Link


@dataclass
class Program:
    """The nodes feeding one material input; `output` = (node index, output identifier, socket type);
    `type` the material input's type ("RGBA" or "VALUE"); `uv_maps` the UV maps its nodes read ("":
    the active render map)."""
    nodes: list
    output: tuple
    type: str = "RGBA"
    uv_maps: list = field(default_factory=list)

    def validate(self, owner: str) -> None:
        if not isinstance(self.nodes, list) or not self.nodes:
            raise SceneError(f"{owner}: a node program needs at least one node")
        if self.type not in SOCKET_TYPES:
            raise SceneError(f"{owner}: node program type {self.type!r} is not one of {', '.join(SOCKET_TYPES)}")
        for i, node in enumerate(self.nodes):
            if not isinstance(node, ProgramNode) or not isinstance(node.kind, str):
                raise SceneError(f"{owner}: program node #{i} must be a ProgramNode, got {node!r}")
            where = f"{owner}, node '{node.name or node.kind}'"
            if not isinstance(node.props, dict) or not isinstance(node.inputs, dict):
                raise SceneError(f"{where}: props and inputs must be mappings")
            for key, value in node.inputs.items():
                if isinstance(value, Link):
                    if not (isinstance(value.node, int) and 0 <= value.node < i):
                        raise SceneError(f"{where}: input '{key}' links node #{value.node}, not an earlier node")
                    if value.source not in SOCKET_TYPES or value.target not in SOCKET_TYPES:
                        raise SceneError(f"{where}: input '{key}' has an unknown socket type")
                    continue
                values = value if isinstance(value, (list, tuple)) else [value]
                if not values or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                         and math.isfinite(v) for v in values):
                    raise SceneError(f"{where}: input '{key}' must be finite numbers or a link, got {value!r}")
        node, output, kind = self.output
        if not (isinstance(node, int) and 0 <= node < len(self.nodes)) or kind not in SOCKET_TYPES:
            raise SceneError(f"{owner}: the program's output {self.output!r} names no node of it")


def validate_programs(material, float_roles) -> None:
    """SceneError for bad programs of a material (engine/scene/model.py Material.programs; float_roles:
    its TEXTURED_INPUTS)."""
    TEXTURED_INPUTS = tuple(float_roles)
    owner = f"Material '{material.name}'"
    programs = material.programs
    if not isinstance(programs, dict):
        raise SceneError(f"{owner}: programs must map input names to node programs, got {programs!r}")
    for role, program in programs.items():
        if role not in COLOR_ROLES + (NORMAL_ROLE,) + TEXTURED_INPUTS:
            raise SceneError(f"{owner}: unknown program input '{role}' (expected one of "
                             f"{', '.join(COLOR_ROLES + (NORMAL_ROLE,) + TEXTURED_INPUTS)})")
        if not isinstance(program, Program):
            raise SceneError(f"{owner}: program of '{role}' must be a Program, got {program!r}")
        program.validate(f"{owner}, input '{role}'")


# -- scene-file fields ---------------------------------------------------------------------------
def _plain(value):
    """Props and constants as JSON data (tuples become lists; dicts and lists recursively)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return int(value)
    return float(value)


def program_json(program: Program) -> dict:
    nodes = []
    for node in program.nodes:
        inputs = {}
        for key, value in node.inputs.items():
            if isinstance(value, Link):
                inputs[key] = {"link": [value.node, value.output, value.source, value.target]}
            else:
                inputs[key] = {"value": _plain(value)}
        nodes.append({"type": node.kind, "name": node.name, "props": _plain(node.props), "inputs": inputs})
    return {"type": program.type, "output": list(program.output), "uv_maps": list(program.uv_maps), "nodes": nodes}


def read_program(entry, owner: str) -> Program:
    if not isinstance(entry, dict) or not isinstance(entry.get("nodes"), list):
        raise SceneError(f"{owner}: a node program must be an object with \"nodes\", got {entry!r}")
    nodes = []
    for i, n in enumerate(entry["nodes"]):
        if not isinstance(n, dict) or not isinstance(n.get("type"), str):
            raise SceneError(f"{owner}: program node #{i} needs a \"type\"")
        inputs = {}
        for key, value in (n.get("inputs") or {}).items():
            if isinstance(value, dict) and "link" in value:
                link = value["link"]
                if not (isinstance(link, list) and len(link) == 4):
                    raise SceneError(f"{owner}: program node #{i} input '{key}': a link is [node, output, from, to]")
                inputs[key] = Link(int(link[0]), str(link[1]), str(link[2]), str(link[3]))
            elif isinstance(value, dict) and "value" in value:
                v = value["value"]
                inputs[key] = tuple(v) if isinstance(v, list) else v
            else:
                raise SceneError(f"{owner}: program node #{i} input '{key}' needs \"value\" or \"link\"")
        nodes.append(ProgramNode(n["type"], str(n.get("name", "")), dict(n.get("props") or {}), inputs))
    out = entry.get("output")
    if not (isinstance(out, list) and len(out) == 3):
        raise SceneError(f"{owner}: a node program's \"output\" is [node, output, type]")
    return Program(nodes, (int(out[0]), str(out[1]), str(out[2])), str(entry.get("type", "RGBA")),
                   [str(u) for u in entry.get("uv_maps", [])])


def programs_json(material) -> dict:
    """{"programs": ...} of a material with node programs, else {} (files stay as they were)."""
    programs = getattr(material, "programs", None) or {}
    return {"programs": {role: program_json(p) for role, p in sorted(programs.items())}} if programs else {}


def read_programs(fields) -> dict:
    """A material entry's "programs" ({role: Program}), {} when absent (fields: engine/scene/fields.py)."""
    if "programs" not in fields:
        return {}
    entry = fields.get("programs")
    if not isinstance(entry, dict):
        fields.fail("programs", "an object of input name: node program", entry)
    return {role: read_program(value, f"{fields.owner}: program '{role}'") for role, value in entry.items()}
