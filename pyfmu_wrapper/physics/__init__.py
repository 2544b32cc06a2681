"""The physics of the paper's models: parameters, equations, Jacobians and exact linear responses."""
