"""The FMUs: their declaration and what runs inside them (the Python slaves, the native step); the host-side build is :mod:`pyfmu_wrapper.fmubuild`."""
