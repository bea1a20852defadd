"""PETSc's coordinate (COO) assembly of the tangent: the matrix is
preallocated once per nonzero pattern from its entries' (row, column)
local indices (``MatSetPreallocationCOOLocal``), after which every
Jacobian hands PETSc one array of values in that order
(``MatSetValuesCOO``): no per-row calls, no column searches, no stash of
off-rank entries (PETSc sets their communication up once). The matrix is
assembled when the call returns.

petsc4py 3.18 (Debian bookworm) does not wrap the two calls, so they are
called in the libpetsc that petsc4py has loaded, through ctypes; newer
petsc4py wraps them and is used directly. Where neither is found,
:func:`available` is False and the caller keeps ``MatSetValuesLocal``.
"""
import ctypes
import os

import numpy as np
from petsc4py import PETSc

_INSERT_VALUES = 1          # PETSc's InsertMode


def _loaded_libpetsc():
    """The libpetsc this process has loaded (petsc4py's), or None."""
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "libpetsc" in line and ".so" in line}
    except OSError:
        return None
    for path in sorted(paths):
        if os.path.basename(path).startswith("libpetsc") and os.path.exists(path):
            try:
                lib = ctypes.CDLL(path)
                lib.MatSetPreallocationCOOLocal.argtypes = [ctypes.c_void_p, ctypes.c_int64,
                                                            ctypes.c_void_p, ctypes.c_void_p]
                lib.MatSetValuesCOO.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
                return lib
            except (OSError, AttributeError):
                continue
    return None


_NATIVE = hasattr(PETSc.Mat, "setPreallocationCOOLocal") and hasattr(PETSc.Mat, "setValuesCOO")
_LIB = None if _NATIVE or os.environ.get("PIMPM_NO_COO") else _loaded_libpetsc()


def available():
    """Can matrices be assembled through COO here? (``PIMPM_NO_COO=1`` in
    the environment turns it off; tests/mpi/jacobian_check.py compares the
    two assemblies.)"""
    if os.environ.get("PIMPM_NO_COO"):
        return False
    return _NATIVE or _LIB is not None


def _check(code):
    """Raise PETSc's error for a nonzero error code (PETSc has printed why)."""
    if code:
        raise PETSc.Error(code)


def preallocate_local(mat, rows, cols):
    """Preallocate ``mat`` (sizes and local-to-global mapping set) for the
    entries at ghosted-local (``rows[k]``, ``cols[k]``). Collective."""
    rows = np.array(rows, dtype=PETSc.IntType)          # copies: PETSc may overwrite them
    cols = np.array(cols, dtype=PETSc.IntType)
    if _NATIVE:
        mat.setPreallocationCOOLocal(rows, cols)
        return
    _check(_LIB.MatSetPreallocationCOOLocal(mat.handle, len(rows), rows.ctypes.data, cols.ctypes.data))


def set_values(mat, values):
    """Replace every entry of ``mat`` by ``values`` (in the preallocation's
    order; entries listed twice are summed, as are those of other ranks);
    the matrix is assembled on return. Collective."""
    values = np.ascontiguousarray(values, dtype=PETSc.ScalarType)
    if _NATIVE:
        mat.setValuesCOO(values, addv=PETSc.InsertMode.INSERT_VALUES)
        return
    _check(_LIB.MatSetValuesCOO(mat.handle, values.ctypes.data, _INSERT_VALUES))
