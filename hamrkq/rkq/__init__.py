"""The RKQ integrator: its step kernel, driver and SciPy ``OdeSolver`` form."""
