"""Shader node graphs evaluated over a wavefront of hits (one NumPy kernel per Blender node type)."""
