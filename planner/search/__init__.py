"""One UAV's search: its costs and objectives, a space-time search around the
others, any-angle smoothing, and the black hole's optimizer-driven search (eq. 8)."""
