"""Solver presets as data: each is a dictionary of PETSc options (and
pimpm's own ``pimpm_*`` settings), refined by the YAML ``solver: {petsc:
...}`` block and the command line. What a preset implies for the rest of
the solver (a direct fallback, rigid-body modes, a symmetric tangent, a
shell matrix) is derived from its options. No PETSc import here: the input
schema reads the names."""

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
