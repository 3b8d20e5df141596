"""Shading hit points: normals and directions, the lighting kernel, direct and area light with their shadow rays, and
the one place secondary rays are born; the passes the stages tell their terms to."""
