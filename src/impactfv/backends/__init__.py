"""Backends: the loops around the point functions. Only the CPU (numba) backend exists today."""
