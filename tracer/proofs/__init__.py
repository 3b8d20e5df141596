"""The proofs that spare rays their exact tests: the margins they rely on, the surfaces as bounds, cones, tiles, culling
and penumbra for shadow rays, the sightlines Embree may meet as they are, and the one planner that decides which
proof spares which rays."""
