"""Runge-Kutta methods as frozen, cited data, in one registry."""
