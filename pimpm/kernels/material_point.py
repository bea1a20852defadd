"""One material point of any registered material model, compiled: the
dispatch of the particle kernels to each model's ``point`` and ``energy``
(:mod:`pimpm.materials.model`; the registry is
:data:`pimpm.materials.MODELS`, whose order gives the model codes), and the
plane-stress thickness solve around a material point.

A kernel that knows its model when it is compiled gets only that model's
code (:func:`model_tag`); a table of several models dispatches per particle
through an if-chain over the registry, generated from it.
"""
import math

import numba
import numpy as np
from numba.extending import overload

from .jit import JIT_OPTIONS, jit

#: a kernel's ``only`` argument when the particles' materials use several models
MIXED = -1
#: number of scratch 3x3 matrices a material point may use
WORKSPACE = 8


def _registry():
    """The registered models in code order (imported when a kernel is
    compiled: the material modules import the kernel helpers)."""
    from ..materials import MODELS
    return list(MODELS.values())


def _dispatcher(functions, arguments):
    """A function ``dispatch(code, *arguments)`` that calls
    ``functions[code](*arguments)``: an if-chain, for numba to compile
    inline."""
    args = ", ".join(arguments)
    lines = [f"def dispatch(code, {args}):"]
    for i in range(len(functions)):
        lines += [f"    {'if' if i == 0 else 'elif'} code == {i}:", f"        return f{i}({args})"]
    lines.append(f"    return f{len(functions) - 1}({args})")
    namespace = {f"f{i}": f for i, f in enumerate(functions)}
    exec("\n".join(lines), namespace)         # noqa: S102 - source generated here from the registry
    # compiled into the kernels that call it (not cached on its own: it has no source file)
    return numba.njit(**JIT_OPTIONS)(namespace["dispatch"])


_POINT_ARGUMENTS = ("prm", "F", "h_in", "h_out", "sigma", "c", "want_c", "w", "D", "in_plane")


def model_tag(code):
    """A value whose numba type says which model a kernel compiles: a tuple
    of ``code + 1`` zeros for one model shared by every particle, ``()`` for
    MIXED. (A tuple's length is part of its type, as with ``axes``; a
    literal int from Python would make numba re-type the kernel at every
    call.)"""
    return () if code == MIXED else (0,) * (code + 1)


def model_point(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    """The material point (:mod:`pimpm.materials.model`) of model code
    ``model`` with packed parameters ``prm``. ``only`` is :func:`model_tag`
    of the model every particle shares (``model`` is then ignored, and only
    that model's code is compiled), or of MIXED (each particle's ``model``
    is dispatched at run time, every model compiled in). Compiled code only:
    the implementation is chosen by :func:`_model_point` from the type of
    ``only``. (Callers pass flags as values, not constants: numba would
    compile every model again for each constant.)"""
    raise NotImplementedError("model_point runs only in compiled kernels")


@overload(model_point, jit_options=JIT_OPTIONS)
def _model_point(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    models = _registry()
    code = len(only.types) - 1
    if code == MIXED:
        dispatch = _dispatcher([m.point for m in models], _POINT_ARGUMENTS)

        def dispatched(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
            dispatch(model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
        return dispatched
    point = models[code].point

    def single(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
        point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
    return single


def model_energy(only, model, prm, F, h):
    """Stored energy per unit reference volume of one particle of model
    code ``model`` (committed history ``h``); ``only`` as in
    :func:`model_point`. Compiled code only."""
    raise NotImplementedError("model_energy runs only in compiled kernels")


@overload(model_energy, jit_options=JIT_OPTIONS)
def _model_energy(only, model, prm, F, h):
    models = _registry()
    code = len(only.types) - 1
    if code == MIXED:
        dispatch = _dispatcher([m.energy for m in models], ("prm", "F", "h"))

        def dispatched(only, model, prm, F, h):
            return dispatch(model, prm, F, h)
        return dispatched
    energy = models[code].energy

    def single(only, model, prm, F, h):
        return energy(prm, F, h)
    return single


@jit
def update_points(models, params, material_of, F, h_in, h_out, sigma, c, want_c, plane_stress, F_inc):
    """The stress update of every particle (G&W step 5): ``material_of[p]``
    indexes ``models`` and ``params``; in plane stress the thickness stretch
    F33 is solved first (:func:`solve_thickness`, writing F and F_inc).
    ``F_inc`` may have zero rows when not in plane stress. Returns the
    number of particles whose thickness solve did not converge."""
    w = np.empty((WORKSPACE, 3, 3))
    D = np.empty((3, 3, 3, 3))
    c_scratch = np.empty((3, 3, 3, 3))
    failed = 0
    for p in range(F.shape[0]):
        m = material_of[p]
        cp = c[p] if want_c else c_scratch
        if plane_stress:
            if not solve_thickness((), models[m], params[m], F[p], F_inc[p], h_in[p], h_out[p], sigma[p],
                                   cp, want_c, w, D):
                failed += 1
        else:
            # every entry of c (False as a value, not a constant: see model_point)
            model_point((), models[m], params[m], F[p], h_in[p], h_out[p], sigma[p], cp, want_c, w, D,
                        plane_stress)
    return failed


#: the thickness Newton's iterations before it gives up (it converges in a few)
THICKNESS_ITERATIONS = 50


@jit
def solve_thickness(only, model, prm, F, F_inc, h_in, h_out, sigma, c, want_c, w, D):
    """Plane stress: a local Newton for F33 so that sigma33 = 0 (d sigma33 /
    d ln F33 = c3333 + sigma33), F and F_inc updated in place; the in-plane
    tangent is condensed, c_abcd - c_ab33 c_33cd / c_3333. ``only``,
    ``model``: as :func:`model_point`. Returns whether it converged within
    THICKNESS_ITERATIONS (an inverted particle has NaN stress: not converged)."""
    # every iteration needs c_3333; a flag that is not a constant, so that numba
    # does not compile the material point once more for a literal True
    need_c = want_c or not want_c
    in_plane = not need_c        # every entry of c: the condensation needs c_ab33, c_33cd
    converged = False
    for _ in range(THICKNESS_ITERATIONS):
        model_point(only, model, prm, F, h_in, h_out, sigma, c, need_c, w, D, in_plane)
        s33 = sigma[2, 2]
        big = 0.0
        for i in range(3):
            for j in range(3):
                big = max(big, abs(sigma[i, j]))
        if abs(s33) <= 1e-13 * (abs(c[2, 2, 2, 2]) + big):
            converged = True
            break
        step = math.exp(-s33 / (c[2, 2, 2, 2] + s33))
        F[2, 2] *= step
        F_inc[2, 2] *= step
    if want_c:
        c2222 = c[2, 2, 2, 2]
        for a in range(2):
            for b in range(2):
                for cc in range(2):
                    for d in range(2):
                        c[a, b, cc, d] -= c[a, b, 2, 2] * c[2, 2, cc, d] / c2222
    return converged
