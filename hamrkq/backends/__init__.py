"""Numerical backends: generated scalar code, its cache, NumPy and numba."""
