"""Exact intersection: Embree's float32 proxies find candidates, the walk tests them in float64, ties between surfaces
met at one point are broken in one order; closest hit and occlusion over every kind."""
