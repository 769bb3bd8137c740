"""Fixed-step baselines: Gauss-Legendre collocation and symplectic splittings."""
