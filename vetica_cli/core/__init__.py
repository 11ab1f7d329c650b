"""numba kernels: plain SI floats and arrays in and out; no I/O, no pandas."""
