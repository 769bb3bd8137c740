"""The symbolic layer: the safe expression parser and :class:`Hamiltonian`."""
