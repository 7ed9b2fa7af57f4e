"""Analytic primitives intersected in float64 NumPy: spheres and quads."""
