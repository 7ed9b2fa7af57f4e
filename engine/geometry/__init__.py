"""Ray queries: every primitive behind one nearest-hit and one shadow-ray query; triangle accelerators (Embree, the report's octree, brute force), analytic shapes, shading normals."""
