"""OpenCL back end: device choice, program cache, kernel launch wrappers for kernels/*.cl.

pyopencl is imported inside functions, so this package imports without it.
"""
