"""The monolithic solver: integrators, steady states by shooting and windows, sweeps and exact responses."""
