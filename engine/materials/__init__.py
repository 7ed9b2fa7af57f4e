"""How surfaces scatter: the BSDF protocol (protocol.py) and its implementations (lambert, mirror,
glass), the material table that picks a BSDF per material kind (table.py), Fresnel and the
specular directions, the nested-dielectric medium stack, and image textures evaluated at hits."""
