"""phongray's benchmark: speed against Embree and POV-Ray, and speed against error."""
