"""Validation of the grid, time, solver, parallel and output sections."""
from collections.abc import Mapping

from .functions import _function_ref
from .checks import (_MISSING, _Section, _bool, _enum, _fail, _float, _float_vector, _fmt, _int,
    _is_int, _is_number, _join, _optional_mapping, _positive, _string)
from ..integrators import INTEGRATORS as _INTEGRATORS
from .schema import (AXES, BOUNDARY_ALIASES, BOUNDARY_TYPES, CONVERGENCE_KEYS, CONVERGENCE_TESTS,
    DEFAULT_OUTPUT_DIRECTORY, DEFAULT_SHAPE_FUNCTIONS, DEFAULT_WEAK_NODE_FRACTION, FORMULATIONS, GRID_KEYS,
    INTEGRATORS, MAX_CUTS, OUTPUT_KEYS, PARALLEL_KEYS, SHAPE_FUNCTIONS, SOLVER_KEYS, SOLVER_PRESETS,
    STRESS_UPDATES, TIME_KEYS)


def _validate_face(b, path, dim, functions):
    """A grid face's condition: a type name, or a prescribed velocity
    {velocity: [vx, vy(, vz)] or {axis: v, ...}, function: NAME}."""
    if not isinstance(b, Mapping):
        b = _enum(b, path, BOUNDARY_TYPES, " (or a mapping with a velocity)")
        return BOUNDARY_ALIASES.get(b, b)
    sec = _Section(b, path, ("velocity", "function"))
    v = sec.required("velocity", f"a list of {dim} numbers or a mapping axis -> number")
    vpath = sec.sub("velocity")
    if isinstance(v, Mapping):
        if not v:
            _fail(vpath, v, f"a list of {dim} numbers or a non-empty mapping axis -> number")
        components = {}
        for axis, value in v.items():
            if axis not in AXES[:dim]:
                _fail(vpath, v, f"axes among {', '.join(AXES[:dim])}")
            components[axis] = _float(value, _join(vpath, axis))
    else:
        components = dict(zip(AXES, _float_vector(v, vpath, dim)))
    return {"velocity": components, "function": _function_ref(sec.optional("function"),
                                                                 sec.sub("function"), functions)}


def _validate_grid(value, path, functions=None):
    sec = _Section(value, path, GRID_KEYS)
    lower = _float_vector(sec.required("lower", "a list of 2 or 3 numbers"), sec.sub("lower"), None)
    dim = len(lower)
    upper = _float_vector(sec.required("upper", f"a list of {dim} numbers"), sec.sub("upper"), dim)
    for i in range(dim):
        if not upper[i] > lower[i]:
            _fail(f"{sec.sub('upper')}[{i}]", upper[i],
                  f"a number > {sec.sub('lower')}[{i}] = {_fmt(lower[i])}")
    cells_path = sec.sub("cells")
    cells_raw = sec.required("cells", f"a list of {dim} integers >= 1")
    if not isinstance(cells_raw, (list, tuple)) or len(cells_raw) != dim:
        _fail(cells_path, cells_raw, f"a list of {dim} integers >= 1")
    cells = [_int(c, f"{cells_path}[{i}]") for i, c in enumerate(cells_raw)]

    shape = sec.optional("shape_functions")
    shape = DEFAULT_SHAPE_FUNCTIONS if shape is _MISSING else _enum(shape, sec.sub("shape_functions"),
                                                     SHAPE_FUNCTIONS)

    faces = [f"{AXES[a]}{side}" for a in range(dim) for side in ("min", "max")]
    bsec = _Section(_optional_mapping(sec.optional("boundary")), sec.sub("boundary"), faces)
    boundary = {}
    for face in faces:
        b = bsec.optional(face)
        boundary[face] = "free" if b is _MISSING else _validate_face(b, bsec.sub(face), dim,
                                                                       functions or {})
    weak = sec.optional("weak_node_fraction")
    weak = DEFAULT_WEAK_NODE_FRACTION if weak is _MISSING else _float(weak, sec.sub("weak_node_fraction"))
    if not 0.0 <= weak < 1.0:
        _fail(sec.sub("weak_node_fraction"), weak, "a number >= 0 and < 1 (0: no extension)")
    grid = {"lower": lower, "upper": upper, "cells": cells, "shape_functions": shape,
            "boundary": boundary, "weak_node_fraction": weak}
    return grid, dim


def _validate_time(value, path, dim, functions=None):
    sec = _Section(value, path, TIME_KEYS)
    integ = sec.optional("integrator")
    integ = "newmark" if integ is _MISSING else _enum(integ, sec.sub("integrator"), INTEGRATORS)
    explicit = integ == "explicit"
    if explicit and sec.optional("dt") is _MISSING:
        dt = None                     # automatic: cfl * h / (wave speed + |v|) every step
    else:
        dt = _positive(sec.required("dt", "a positive number"), sec.sub("dt"))
    end_raw = sec.required("end_time", "a positive number >= time.dt")
    end_time = _positive(end_raw, sec.sub("end_time"))
    if dt is not None and end_time < dt:
        _fail(sec.sub("end_time"), end_raw, f"a number >= time.dt = {_fmt(dt)}")
    cfl = sec.optional("cfl")
    cfl = 0.5 if cfl is _MISSING else _float(cfl, sec.sub("cfl"), "a number in (0, 1]")
    if not 0.0 < cfl <= 1.0:
        _fail(sec.sub("cfl"), cfl, "a number in (0, 1]")
    update = sec.optional("stress_update")
    update = "musl" if update is _MISSING else _enum(update, sec.sub("stress_update"), STRESS_UPDATES)
    for key in ("cfl", "stress_update"):
        if sec.has(key) and not explicit:
            _fail(sec.sub(key), sec.data[key], "to be given only with time.integrator: explicit")
    formulation = sec.optional("formulation")
    formulation = "velocity" if formulation is _MISSING else _enum(
        formulation, sec.sub("formulation"), FORMULATIONS)
    if sec.has("formulation") and explicit:
        _fail(sec.sub("formulation"), sec.data["formulation"],
              "to be given only with an implicit integrator (explicit MPM uses time.stress_update; "
              "musl is the explicit momentum formulation)")
    if formulation == "momentum" and integ == "quasi_static":
        _fail(sec.sub("formulation"), sec.data["formulation"],
              "'velocity' with time.integrator: quasi_static (the momentum formulation needs "
              "inertia: without the mass term its tangent K R is singular wherever the "
              "particles do not determine the nodal values)")
    gravity = sec.optional("gravity")
    gravity = [0.0] * dim if gravity is _MISSING else \
        _float_vector(gravity, sec.sub("gravity"), dim)
    gravity_function = _function_ref(sec.optional("gravity_function"), sec.sub("gravity_function"),
                                     functions or {})
    dt_initial = sec.optional("dt_initial")
    dt_initial = dt if dt_initial is _MISSING else _positive(dt_initial, sec.sub("dt_initial"))
    if dt is not None and dt_initial > dt:
        _fail(sec.sub("dt_initial"), dt_initial, f"a number <= time.dt = {_fmt(dt)}")
    ramp = sec.optional("ramp_factor")
    ramp = 1.2 if ramp is _MISSING else _float(ramp, sec.sub("ramp_factor"), "a number >= 1")
    if ramp < 1.0:
        _fail(sec.sub("ramp_factor"), ramp, "a number >= 1")
    cuts = sec.optional("max_cuts")
    cuts = 4 if cuts is _MISSING else _int(cuts, sec.sub("max_cuts"), minimum=0)
    if cuts > MAX_CUTS:        # each cut halves the step: an unbounded count creeps on forever
        _fail(sec.sub("max_cuts"), sec.data["max_cuts"], f"an integer from 0 to {MAX_CUTS} (each cut halves "
                                                           f"the step: {MAX_CUTS} cuts take it to 1e-15 of itself)")
    easy = sec.optional("easy_newton_iterations")
    easy = 6 if easy is _MISSING else _int(easy, sec.sub("easy_newton_iterations"), minimum=1)
    limit = sec.optional("max_particle_displacement")
    limit = None if limit is _MISSING else _positive(limit, sec.sub("max_particle_displacement"))
    out = {"integrator": integ, "dt": dt, "end_time": end_time, "gravity": gravity,
           "gravity_function": gravity_function,
           "dt_initial": dt_initial, "ramp_factor": ramp, "max_cuts": cuts,
           "easy_newton_iterations": easy, "max_particle_displacement": limit,
           "cfl": cfl, "stress_update": update, "formulation": formulation}
    out.update(_integrator_parameters(sec, integ))
    return out


def _integrator_parameters(sec, integrator):
    """The ``time`` keys the chosen integrator declares (pimpm/integrators),
    each a number in its range; a key of another integrator is refused."""
    declared = _INTEGRATORS[integrator].parameters
    out = {}
    for cls in _INTEGRATORS.values():
        for key in cls.parameters:
            if key not in declared and sec.has(key):
                _fail(sec.sub(key), sec.data[key], f"to be given only with time.integrator: {cls.name}")
    for key, p in declared.items():
        value = sec.optional(key)
        if value is _MISSING:
            out[key] = p.default
            continue
        expected = f"a number in [{p.lower:.6g}, {p.upper:.6g}] ({p.meaning})"
        x = _float(value, sec.sub(key), expected)
        if not p.lower - 1e-12 * max(1.0, abs(p.lower)) <= x <= p.upper + 1e-12 * max(1.0, abs(p.upper)):
            _fail(sec.sub(key), value, expected)
        out[key] = min(max(x, p.lower), p.upper)      # -0.3333333333 stands for -1/3
    return out


def _petsc_value(value, path):
    if value is None:
        return ""  # option without a value (a flag, e.g. ksp_monitor)
    if isinstance(value, bool):
        return "true" if value else "false"
    if _is_int(value):
        return str(int(value))
    if _is_number(value):
        return repr(float(value))
    if isinstance(value, str):
        return value
    _fail(path, value, "a scalar option value (string, number, boolean or empty)")


def _validate_solver(value, path):
    sec = _Section(_optional_mapping(value), path, SOLVER_KEYS)
    raw = _optional_mapping(sec.optional("petsc"))
    ppath = sec.sub("petsc")
    if not isinstance(raw, Mapping):
        _fail(ppath, raw, "a mapping of PETSc option names to values")
    petsc = {}
    for key, val in raw.items():
        kpath = _join(ppath, key)
        if not isinstance(key, str):
            _fail(kpath, key, "a PETSc option name (a string)")
        name = key.strip().lstrip("-")
        if not name or any(ch.isspace() for ch in name):
            _fail(kpath, key, "a PETSc option name without spaces, e.g. snes_rtol")
        if name in petsc:
            _fail(kpath, key, f"each PETSc option given once ({name!r} is repeated)")
        if name in ("options_file", "options_file_yaml", "options_left"):
            # PETSc reads options files when it starts, before the input is read (issue 32: it
            # was silently ignored)
            _fail(kpath, val, f"a solver option: give -{name} FILE on the command line (PETSc reads "
                              f"options files when it starts)")
        petsc[name] = _petsc_value(val, kpath)
    preset = sec.optional("preset")
    preset = "mumps" if preset is _MISSING else _enum(preset, sec.sub("preset"), SOLVER_PRESETS)
    fallback = sec.optional("fallback")
    fallback = True if fallback is _MISSING else _bool(fallback, sec.sub("fallback"))
    # the most free dofs the direct fallback factorizes (auto: by dimension, pimpm.presets)
    max_dofs = sec.optional("fallback_max_dofs")
    if max_dofs is _MISSING or max_dofs == "auto":
        max_dofs = "auto"
    elif not _is_int(max_dofs) or max_dofs < 1:
        _fail(sec.sub("fallback_max_dofs"), max_dofs, "an integer >= 1 or auto")
    else:
        max_dofs = int(max_dofs)
    conv = _Section(_optional_mapping(sec.optional("convergence")), sec.sub("convergence"),
                    CONVERGENCE_KEYS)
    test = conv.optional("test")
    test = "petsc" if test is _MISSING else _enum(test, conv.sub("test"), CONVERGENCE_TESTS)
    tols = {}
    for key, default in (("displacement_tolerance", 1e-6), ("energy_tolerance", 1e-12)):
        v = conv.optional(key)
        tols[key] = default if v is _MISSING else _positive(v, conv.sub(key))
    free = sec.optional("free_dofs_only")
    free = True if free is _MISSING else _bool(free, sec.sub("free_dofs_only"))
    # true, false or auto (on in 3D: pimpm.presets.resolve says why)
    automatic = {}
    for key in ("reuse_factorization", "linear_predictor"):
        given = sec.optional(key)
        if given is _MISSING or given == "auto":
            automatic[key] = "auto"
        elif isinstance(given, bool):
            automatic[key] = given
        else:
            _fail(sec.sub(key), given, "true, false or auto")
    return {"preset": preset, "fallback": fallback, "fallback_max_dofs": max_dofs,
            "convergence": dict(test=test, **tols), "petsc": petsc, "free_dofs_only": free, **automatic}


#: the default rebalance threshold: an implicit repartition makes a new matrix
#: and solver, an explicit one only a DMDA and a migration, so the explicit
#: step keeps its ranks closer to even (measured on the 2-rank explicit billet:
#: mean imbalance 1.048 and 18.6 s at 1.1, 1.010 and 17.4 s at 1.02)
REBALANCE_THRESHOLD = {"implicit": 1.1, "explicit": 1.02}


def _validate_parallel(value, path, explicit=False):
    """How ranks share the grid: ``balance`` (ownership ranges chosen from the
    particles; false: PETSc's even split) and ``rebalance_threshold`` (the
    particle imbalance above which a step repartitions first, >= 1; its
    default depends on whether the time integrator is ``explicit``)."""
    sec = _Section(_optional_mapping(value), path, PARALLEL_KEYS)
    balance = sec.optional("balance")
    balance = True if balance is _MISSING else _bool(balance, sec.sub("balance"))
    threshold = sec.optional("rebalance_threshold")
    default = REBALANCE_THRESHOLD["explicit" if explicit else "implicit"]
    threshold = default if threshold is _MISSING else _float(threshold, sec.sub("rebalance_threshold"))
    if not threshold >= 1.0:
        _fail(sec.sub("rebalance_threshold"), threshold, "a number >= 1 (the largest over the mean particle count)")
    return {"balance": balance, "rebalance_threshold": threshold}


def _validate_output(value, path, source_name):
    sec = _Section(_optional_mapping(value), path, OUTPUT_KEYS)
    directory = sec.optional("directory")
    if directory is _MISSING:
        directory = f"{source_name}_output" if source_name else DEFAULT_OUTPUT_DIRECTORY
    else:
        directory = _string(directory, sec.sub("directory"), "a non-empty directory path")
    every = sec.optional("every")
    every = 1 if every is _MISSING else _int(every, sec.sub("every"))
    checkpoint = sec.optional("checkpoint_every")
    checkpoint = 0 if checkpoint is _MISSING else _int(checkpoint, sec.sub("checkpoint_every"), minimum=0)
    return {"directory": directory, "every": every, "checkpoint_every": checkpoint}
