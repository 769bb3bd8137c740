"""SciPy's ``solve_ivp`` methods as baselines that return a :class:`~hamrkq.Solution`."""
