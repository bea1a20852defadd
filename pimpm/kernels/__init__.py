"""Compiled per-particle kernels (numba, cached on disk next to this package).

The per-particle work of every Newton iteration runs here, in loops compiled
once per installation (``@njit(cache=True)``):

* :mod:`.small`: 3x3 helpers (determinant, inverse, products) on scalars;
* :mod:`.material_point`: the dispatch to each material model's compiled
  point and energy (:mod:`pimpm.materials`), the plane-stress thickness solve;
* :mod:`.particle_step`: the fused kernels of the implicit step: deformation
  increment, material point, internal force (residual) and element blocks of
  the consistent tangent accumulated into the matrix values;
* :mod:`.stress`: the explicit step's transfers with the internal force, the
  internal force of the stresses at t (HHT), the stored energy;
* :mod:`.transfer`: shape functions, scatters and gathers;
* :mod:`.pattern`: the nonzero pattern of the tangent from the particle
  footprints (block CSR over the ghosted local nodes);
* :mod:`.reorder`: the gather of particle rows that reorders and migrates
  the particle storage after every step;
* :mod:`.jit`: the decorator, and where the compiled code is cached.

There is one implementation of each of these, the compiled one; independent
numpy references live in the tests (``tests/reference/``), which compare
the kernels with them to round-off (tests/test_kernels.py).
"""
