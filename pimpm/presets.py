"""Solver presets as data: each is a dictionary of PETSc options (and
pimpm's own ``pimpm_*`` settings), refined by the YAML ``solver: {petsc:
...}`` block and the command line. What a preset implies for the rest of
the solver (a direct fallback, rigid-body modes, a symmetric tangent, a
shell matrix) is derived from its options. No PETSc import here: the input
schema reads the names."""
from dataclasses import dataclass

#: GAMG settings, measured on whole runs of the 50% billet (docs/PERFORMANCE.md,
#: scripts/bench_presets.py): plain (unsmoothed) aggregation keeps GMRES at
#: ~37 iterations per Newton step to the end with no direct fallback, where
#: smoothed aggregation (PETSc's default, nsmooths 1) climbs to 150 per step
#: and falls back to MUMPS in 37 of 166 Newton steps as the billet is crushed;
#: a drop threshold of 0.02 and 3 smoothing steps per level.
GAMG = {"pc_type": "gamg", "pc_gamg_agg_nsmooths": "0", "pc_gamg_threshold": "0.02",
        "mg_levels_ksp_max_it": "3"}

#: name -> PETSc options (what else a preset implies is derived from them:
#: :func:`iterative`, :func:`needs_symmetric_tangent`, :func:`matrix_free`). No preset
#: marks the tangent SPD: it is symmetric for hyperelastic materials in the
#: velocity formulation, but the geometric stiffness of a body under
#: compression can make it indefinite (CG reports DIVERGED_INDEFINITE_MAT at
#: 50% on the billet), and MUMPS's SPD factorization (SYM=1) would not do then.
PRESETS = {
    "mumps": {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"},
    "cg-gamg": {"ksp_type": "cg", **GAMG, "ksp_rtol": "1e-8", "ksp_max_it": "1000"},
    "gmres-gamg": {"ksp_type": "gmres", **GAMG, "ksp_rtol": "1e-8",
                   "ksp_gmres_restart": "100", "ksp_max_it": "1000"},
    # hypre's BoomerAMG with HMIS coarsening, extended+i interpolation and a
    # strong threshold of 0.5 (hypre's advice for 3D): 11-14 GMRES iterations
    # a Newton iteration on the billet at 0.5, 0.25 and 0.125 cm where GAMG's
    # grow from 35 to 72, and 35-54 against 54-75 on the 3D upsetting's
    # plastic tangents at 1 and 0.5 mm; 0.84 of the time of BoomerAMG's
    # defaults on the 0.25 cm billet and 0.69 on the 1 mm upsetting (2 ranks,
    # alternating whole runs); slower than GAMG at a million particles in 3D,
    # 138.7 against 79.5 s a step (docs/PERFORMANCE.md, "Multigrid on MPM
    # tangents")
    "gmres-hypre": {"ksp_type": "gmres", "pc_type": "hypre", "pc_hypre_type": "boomeramg",
                    "pc_hypre_boomeramg_strong_threshold": "0.5", "pc_hypre_boomeramg_coarsen_type": "HMIS",
                    "pc_hypre_boomeramg_interp_type": "ext+i", "ksp_rtol": "1e-8",
                    "ksp_gmres_restart": "100", "ksp_max_it": "1000"},
    # Sulsky & Kaul's Jacobian-free Newton-Krylov: the operator is the finite-
    # difference directional derivative (their eq. 2.4.18); the assembled
    # tangent serves only as preconditioner.
    "jfnk": {"snes_mf_operator": "", "ksp_type": "gmres", **GAMG, "ksp_rtol": "1e-8",
             "ksp_gmres_restart": "100", "ksp_max_it": "1000"},
    # Fully matrix-free: a shell matrix whose product is the analytic
    # directional derivative of the residual (pimpm_tangent shell, read by
    # pimpm, not PETSc); Jacobi from its diagonal.
    "matrix-free": {"pimpm_tangent": "shell", "ksp_type": "gmres", "pc_type": "jacobi", "ksp_rtol": "1e-8",
                    "ksp_gmres_restart": "200", "ksp_max_it": "5000"},
}

#: the most free dofs the direct fallback factorizes, by dimension (``auto``):
#: a 3D factorization's work grows as the square of its unknowns (nested
#: dissection): the 0.5 mm 3D upsetting's free dofs (about a tenth of 266,511) take 2.2 s
#: (docs/PERFORMANCE.md, "3D at 0.5 mm"), so by that rule 100,000 take about
#: half a minute, longer than a step of the iterative solver there; 2D work
#: grows as the 1.5 power, and its cap only guards against absurd sizes
FALLBACK_MAX_DOFS = {2: 2_000_000, 3: 100_000}
#: the direct solver used when the iterative one fails (prefix "fallback_")
FALLBACK_OPTIONS = {"fallback_ksp_type": "preonly", "fallback_pc_type": "lu",
                    "fallback_pc_factor_mat_solver_type": "mumps"}


def iterative(options):
    """Does the Krylov solver iterate (anything but ``preonly``)?"""
    return options.get("ksp_type", "preonly") != "preonly"


def needs_symmetric_tangent(options):
    """Does the Krylov solver assume a symmetric operator (CG)?"""
    return options.get("ksp_type") == "cg"


def matrix_free(options):
    """Is the tangent a shell matrix (its analytic product, no matrix stored)?"""
    return options.get("pimpm_tangent") == "shell"


def petsc_options(options):
    """The options for PETSc's database: without pimpm's own settings."""
    return {k: v for k, v in options.items() if not k.startswith("pimpm_")}


# ------------------------------------------------------------ option resolution
#: the program's defaults for PETSc options (the preset, then the YAML, then
#: the command line override them). The tolerances: answers within 5e-9
#: relative of runs converged to rtol 1e-13 on the billet, the colliding
#: disks and the J2 upsetting (scripts/newton_tolerances.py,
#: docs/PERFORMANCE.md), so that runs on different numbers of ranks agree to
#: 1e-8; rtol 1e-6 moves the upsetting's force by 1.2e-8, atol 1e-10 the
#: disks' energies by 8.5e-8.
DEFAULT_SOLVER_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": "1e-8",
    "snes_atol": "1e-12",        # the residual is dimensionless (Sulsky & Kaul 3.2.2)
    "snes_max_it": "30",
}

_TRUE, _FALSE = ("", "1", "true", "yes", "on"), ("0", "false", "no", "off")


@dataclass(frozen=True)
class SolverPlan:
    """What the Newton solver is made of, resolved from the input and the
    command line before any PETSc object exists (:func:`resolve`)."""
    preset: str
    #: the program's options for PETSc's database: defaults < preset <
    #: per-problem adjustments < YAML ``solver.petsc`` (the command line, already
    #: in the database, wins over all of them when they are inserted)
    options: dict
    iterative: bool
    matrix_free: bool
    #: iterative solve with a direct fallback (pimpm.linear.FallbackKSP)
    fallback: bool
    #: a direct solve of the free dofs only (pimpm.linear.FreeDofsKSP)
    free_dofs: bool
    #: the tangent matrix carries the symmetry flags
    symmetric: bool
    #: GAMG gets the rigid-body modes
    near_null_space: bool
    #: the tangent is assembled on the step's particle pattern
    on_pattern: bool
    mf_operator: bool
    #: ("petsc", None, None) or ("guilkey_weiss", displacement tolerance, energy tolerance)
    convergence: tuple
    #: the direct solve on the free dofs factorizes once per step, and GMRES
    #: preconditioned by that factorization solves the step's later Newton systems
    reuse_factorization: bool = False
    #: pimpm.line_search.FullStepFirst's threshold (PETSc's basic line search
    #: with its pre-check), or None: the options' PETSc line search alone
    full_step_first: float = None
    #: a step that starts from rest begins Newton at the linearized response to
    #: its prescribed motion (pimpm.solver.NewtonSolver.linear_predictor)
    linear_predictor: bool = False
    #: the direct fallback factorizes at most this many free dofs (FallbackKSP)
    fallback_max_dofs: int = None


def shown(value):
    """An option's value as a message shows it: on one line (control
    characters escaped) and at most 80 characters."""
    text = str(value)
    if not text.isprintable():
        text = repr(text)
    return text if len(text) <= 80 else text[:77] + "..."


def _word(command_line, name, default):
    return command_line.get(name, default)


def _flag(command_line, name, default):
    if name not in command_line:
        return default
    text = str(command_line[name]).strip().lower()
    if text in _TRUE or text in _FALSE:
        return text in _TRUE
    raise ValueError(f"-{name} {shown(command_line[name])}: expected true or false (1 or 0)")


def _number(command_line, name, default):
    """A positive, finite number option (the Guilkey-Weiss tolerances)."""
    if name not in command_line:
        return default
    try:
        value = float(command_line[name])
    except ValueError:
        value = None
    if value is None or not 0.0 < value < float("inf"):     # NaN too (issue 32)
        raise ValueError(f"-{name} {shown(command_line[name])}: expected a positive, finite number")
    return value


#: the factorization a step reuses (``reuse_factorization``: it preconditions
#: GMRES on the step's later Newton systems): MUMPS's block low-rank
#: factorization (ICNTL(35) = 2), the fronts compressed before they are
#: factorized (ICNTL(36) = 1), at a dropping threshold CNTL(7) of 1e-4. On the
#: 0.5 mm 3D upsetting's first four steps (2 ranks, docs/PERFORMANCE.md "3D at
#: 0.5 mm") a factorization takes 1.9-2.8 s instead of 3.7 s, a triangular solve
#: 32 ms instead of 42 ms, and the largest rank 2.2 GB instead of 3.1 GB, for the
#: same Newton iterations and platen force (to 1e-10); at 1e-3 step 1 took 16
#: Newton iterations instead of 8
REUSE_FACTORIZATION_OPTIONS = {"mat_mumps_icntl_35": "2", "mat_mumps_icntl_36": "1", "mat_mumps_cntl_7": "1e-4"}

#: the options a run's unilateral contact needs, by the kind of its terms
#: (their ``contact_kind``). With rigid tools (pimpm.terms.contact), l2's step
#: where the full Newton step does not cut the residual norm to
#: FULL_STEP_FIRST of it (pimpm.line_search.FullStepFirst, PETSc's basic with
#: a pre-check): a Newton step taken where a corner has just left the tool
#: (the predictor lags a withdrawing plate by a fraction of a cell) lets the
#: body spring back through it; bt's backtracking then crawls
#: (inputs/plate_release.yaml unloading: 7-12 iterations, 8-24 backtracks per
#: step), l2's secant on the residual norm does not (4 iterations); once the
#: contact states have settled the full step is taken with one residual where
#: l2 spends three (docs/PERFORMANCE.md, the frictional billet). Between
#: deformable bodies (pimpm.terms.pairs) PETSc's l2 where a pair has friction:
#: at large steps bt needs more iterations and cuts to settle stick and slip
#: (the disk sliding down its slope at 100x the explicit step: 7.3 iterations
#: a step, 1 cut, against 5.9; Nairn's block at 1000x: 4 cuts against 1), and
#: the full step first saved nothing there (the slope: 1-3% more iterations;
#: the stack at 100x: 12 cuts against 9); frictionless and bonded pairs keep
#: bt, since l2 costs two more residuals an iteration and settles them no
#: faster (the four disks: 1.47 against 1.76 times the shared field's time,
#: the same 274 Newton iterations; scripts/bench_contact_pairs.py). None has a
#: divergence test: the residual at the predictor of a body resting on a tool
#: or another body is round-off small, and the first iterates (the contact
#: zone settling) exceed 1e4 times it; PETSc's default divergence tolerance
#: then stops Newton (inputs/friction_onset.yaml at dt = 0.05: 4 cuts and a
#: failed run; without it no cut and 3.8 Newton iterations a step)
_NO_DIVERGENCE_TEST = {"snes_divergence_tolerance": "-1"}
CONTACT_OPTIONS = {"tool": dict(_NO_DIVERGENCE_TEST, snes_linesearch_type="basic"),
                   "frictional pair": dict(_NO_DIVERGENCE_TEST, snes_linesearch_type="l2"),
                   "pair": _NO_DIVERGENCE_TEST}
#: the contact kinds whose line search is pimpm.line_search.FullStepFirst,
#: unless the input or the command line names a line search
FULL_STEP_FIRST_KINDS = ("tool",)
#: the full Newton step is kept when it cuts the residual norm to at most this
#: fraction. The frictional billet (2 ranks, one run each): at mu = 0.3, 0.1,
#: 0.25 and 0.5 keep 109, 164 and 208 of about 245 Newton steps whole, for the
#: same Newton iterations; at mu = 0.1, 0.5 cut a step once (45 steps, 272
#: iterations) where 0.25 and 0.1 did not (249 and 253)
FULL_STEP_FIRST = 0.25


def resolve(solver_config, command_line, *, symmetric, dim, assembles_on_pattern, coo, asymmetry="",
            contact=()):
    """The solver of a run from the input's ``solver`` section, the command
    line (``command_line``: PETSc's options database as {name: value}, no
    dash) and what the step's problem is like (a ``symmetric`` tangent, the
    dimension, whether it assembles on the particles' pattern through COO
    values; ``asymmetry`` says why it is not symmetric, for the message;
    ``contact``: the kinds of its unilateral contact terms, CONTACT_OPTIONS' keys). A pure function; ValueError naming the option or key and its value."""
    preset = _word(command_line, "pimpm_preset", solver_config["preset"])
    if preset not in PRESETS:
        raise ValueError(f"-pimpm_preset {shown(preset)}: expected one of {', '.join(PRESETS)}")
    preset_options = PRESETS[preset]
    is_iterative = iterative(preset_options)
    is_matrix_free = matrix_free(preset_options)
    if needs_symmetric_tangent(preset_options) and not symmetric:
        where = "-pimpm_preset" if "pimpm_preset" in command_line else "solver.preset"
        raise ValueError(f"{where} = {preset!r}: expected a preset for non-symmetric "
                         f"tangents (gmres-gamg, mumps, jfnk or matrix-free) with {asymmetry}")
    wants_fallback = _flag(command_line, "pimpm_fallback", bool(solver_config["fallback"]))
    use_fallback = is_iterative and not is_matrix_free and wants_fallback
    options = dict(DEFAULT_SOLVER_OPTIONS)
    for kind in sorted(contact):
        options.update(CONTACT_OPTIONS[kind])
    options.update(petsc_options(preset_options))
    if use_fallback:
        options.update(FALLBACK_OPTIONS)
    if symmetric:
        # a symmetric tangent is factorized by MUMPS's LDL^T (half the work
        # of LU); -pc_type lu on the command line or in the YAML still wins
        options.update({k: "cholesky" for k, v in options.items() if k.endswith("pc_type") and v == "lu"})
    if dim == 2:
        # MUMPS's ordering: AMF. On the 0.25 cm billet its analysis takes 12 ms
        # where the automatic choice takes 170 ms, for the same factorization
        # cost; the pattern changes as particles move, so the analysis is
        # repeated at most steps (docs/PERFORMANCE.md)
        options.update({"mat_mumps_icntl_7": "2", "fallback_mat_mumps_icntl_7": "2"})
    options.update(solver_config["petsc"])          # the YAML refines the preset
    setting = lambda key: command_line.get(key, options.get(key))  # noqa: E731
    mf_operator = "snes_mf_operator" in command_line or "snes_mf_operator" in options
    on_pattern = assembles_on_pattern and not is_matrix_free
    free_dofs = bool(solver_config.get("free_dofs_only", True) and on_pattern and coo and not use_fallback
                     and not mf_operator and setting("ksp_type") == "preonly"
                     and setting("pc_type") in ("lu", "cholesky"))
    reuse = _automatic(solver_config.get("reuse_factorization", False), dim) and free_dofs
    if reuse:
        # the step's one factorization only preconditions GMRES: MUMPS's block
        # low-rank one will do (the input's and the command line's options win)
        for key, value in REUSE_FACTORIZATION_OPTIONS.items():
            options.setdefault(key, value)
    linear_predictor = _automatic(solver_config.get("linear_predictor", False), dim)
    conv = solver_config["convergence"]
    test = _word(command_line, "pimpm_convergence_test", conv["test"])
    # checked whichever test runs: a bad option is bad input even where it is not used
    tolerances = (_number(command_line, "pimpm_gw_displacement_tol", float(conv["displacement_tolerance"])),
                  _number(command_line, "pimpm_gw_energy_tol", float(conv["energy_tolerance"])))
    if test == "guilkey_weiss":
        convergence = (test,) + tolerances
    elif test == "petsc":
        convergence = (test, None, None)
    else:
        raise ValueError(f"-pimpm_convergence_test {shown(test)}: expected petsc or guilkey_weiss")
    # a line search named in the input or on the command line is taken as it is
    named = any("snes_linesearch_type" in source for source in (command_line, solver_config["petsc"], preset_options))
    full_step_first = None
    if not named and set(contact) & set(FULL_STEP_FIRST_KINDS):
        full_step_first = FULL_STEP_FIRST
    max_dofs = solver_config.get("fallback_max_dofs", "auto")
    if max_dofs == "auto":
        max_dofs = FALLBACK_MAX_DOFS[dim]
    return SolverPlan(preset=preset, options=options, iterative=is_iterative, matrix_free=is_matrix_free,
                      fallback=use_fallback, free_dofs=free_dofs, symmetric=symmetric and not is_matrix_free,
                      near_null_space=is_iterative and not is_matrix_free, on_pattern=on_pattern,
                      mf_operator=mf_operator, convergence=convergence, reuse_factorization=reuse,
                      linear_predictor=linear_predictor, fallback_max_dofs=max_dofs,
                      full_step_first=full_step_first)


def _automatic(setting, dim):
    """``solver.reuse_factorization`` and ``solver.linear_predictor``: true,
    false, or auto, which is on in 3D. Measured on the 0.5 mm 3D upsetting
    (docs/PERFORMANCE.md, "3D at 0.5 mm"): one factorization per step halves
    the steps' time, and the linearized start takes the first step through in
    7 Newton iterations where it needed a cut and 20. In 2D the factorization
    is cheap (the billet's time is the same either way) and the predictor,
    which helps there too (billet step 1: 2 iterations instead of 6), is left
    off so that the documented 2D answers and iteration counts stand."""
    return dim == 3 if setting == "auto" else bool(setting)
