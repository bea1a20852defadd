"""Compiled per-particle kernels (numba, cached on disk next to this package).

The per-particle work of every Newton iteration runs here, in loops compiled
once per installation (``@njit(cache=True)``):

* :mod:`.small`: 3x3 helpers (determinant, inverse, products) on scalars;
* :mod:`.material_point`: the stress, the spatial tangent and the history
  update of one material point for every material model;
* :mod:`.particle_step`: the fused kernels of the implicit step: deformation
  increment, material point, internal force (residual) and element blocks of
  the consistent tangent accumulated into the matrix values;
* :mod:`.pattern`: the nonzero pattern of the tangent from the particle
  footprints (block CSR over the ghosted local nodes);
* :mod:`.reorder`: the gather of particle rows that reorders and migrates
  the particle storage after every step;
* :mod:`.jit`: the decorator, and where the compiled code is cached.

The numpy versions they replace stay as references: the material models in
:mod:`pimpm.materials`, the element kernels in :mod:`pimpm.assembly` and the
kinematics in :mod:`pimpm.kinematics`; tests check compiled == numpy to
round-off (tests/test_kernels.py).
"""
