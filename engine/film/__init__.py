"""Where samples go: the film accumulator (sums, means, the variance of the mean), render passes, the error estimate, the denoiser, output and image files."""
