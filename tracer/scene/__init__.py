"""The scene as the tracer holds it: float64 surfaces and lights re-centred on the eye, the camera's primary rays, the
named ray batches, the surface kinds, and the render's options (classic mistakes, accepted offsets)."""
