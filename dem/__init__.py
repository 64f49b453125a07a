"""Numba 2D DEM of disks: sample generation, biaxial and strain-rotation experiments, stereological fabric."""
