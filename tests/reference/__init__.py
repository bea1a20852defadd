"""Independent numpy references of what pimpm computes in compiled kernels:
the material models (:mod:`.materials`). The tests compare the kernels with
them to round-off; they are never imported by pimpm."""
