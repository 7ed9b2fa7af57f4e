"""How surfaces scatter: BSDFs, Fresnel, and image textures evaluated at hits."""
