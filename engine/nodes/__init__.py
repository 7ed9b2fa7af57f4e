"""Shader nodes (package docstring: engine/nodes/__init__.py is nodes-core's)."""
