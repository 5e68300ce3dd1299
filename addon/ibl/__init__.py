"""Image-based lighting engine: equirect geometry, spherical harmonics, sampling, blurred maps."""
