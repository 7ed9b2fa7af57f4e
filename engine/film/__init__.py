"""Where samples go: the tile film, render passes, the error estimate, the denoiser, output and image files."""
