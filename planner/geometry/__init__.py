"""Grids and geometry: shortest grid paths, clearance from obstacles, the
encoding of a path as an optimizer's vector."""
