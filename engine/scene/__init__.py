"""The scene model (camera, materials, primitives, lights, images), its validation, its files, camera rays and the built-in scenes."""
