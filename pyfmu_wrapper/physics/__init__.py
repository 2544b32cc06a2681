"""The shared core every model builds on: element kernels (the paper's equations), parameter and unit types, Jacobian helpers; imports nothing above it."""
