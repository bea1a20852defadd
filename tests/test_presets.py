"""Solver presets are data (pimpm/presets.py): what each implies is derived
from its options, the input schema's names are the presets' own, and the
solver of a run is resolved from the input and the command line by a pure
function (presets.resolve)."""
import pytest

from pimpm import presets
from pimpm.config.schema import SOLVER_PRESETS


def test_what_a_preset_implies_is_derived_from_its_options():
    derived = {name: (presets.iterative(o), presets.needs_symmetric_tangent(o), presets.matrix_free(o))
               for name, o in presets.PRESETS.items()}
    assert derived == {"mumps": (False, False, False), "cg-gamg": (True, True, False),
                       "gmres-gamg": (True, False, False), "gmres-hypre": (True, False, False),
                       "jfnk": (True, False, False),
                       "matrix-free": (True, False, True)}
    assert presets.iterative({}) is False          # PETSc's KSP default here is preonly


def test_pimpm_settings_stay_out_of_the_petsc_options_and_names_are_shared():
    options = presets.petsc_options(presets.PRESETS["matrix-free"])
    assert "pimpm_tangent" not in options and options["pc_type"] == "jacobi"
    assert SOLVER_PRESETS == tuple(presets.PRESETS)


# ---------------------------------------------------------------- resolve()

SOLVER = {"preset": "mumps", "fallback": True, "petsc": {}, "free_dofs_only": True,
          "convergence": {"test": "petsc", "displacement_tolerance": 1e-6, "energy_tolerance": 1e-12}}
PROBLEM = {"symmetric": True, "dim": 2, "assembles_on_pattern": True, "coo": True}


def resolve(command_line=None, problem=None, **solver):
    return presets.resolve(dict(SOLVER, **solver), command_line or {}, **dict(PROBLEM, **(problem or {})))


def test_options_are_defaults_then_preset_then_adjustments_then_yaml():
    plan = resolve()
    assert plan.preset == "mumps" and not plan.iterative and not plan.fallback
    assert plan.options["snes_rtol"] == presets.DEFAULT_SOLVER_OPTIONS["snes_rtol"]
    # a symmetric tangent: MUMPS's LDL^T; the plane: AMF ordering
    assert plan.options["pc_type"] == "cholesky" and plan.options["mat_mumps_icntl_7"] == "2"
    assert resolve(problem={"symmetric": False}).options["pc_type"] == "lu"
    assert "mat_mumps_icntl_7" not in resolve(problem={"dim": 3}).options
    # the YAML wins over the preset and the adjustments
    plan = resolve(petsc={"pc_type": "lu", "snes_rtol": "1e-10"})
    assert plan.options["pc_type"] == "lu" and plan.options["snes_rtol"] == "1e-10"
    # preset options win over the defaults
    assert resolve(preset="cg-gamg").options["ksp_type"] == "cg"


def test_contact_sets_its_line_search_and_no_divergence_test_unless_the_yaml_says():
    """Rigid tools and frictional pairs: PETSc's basic line search with
    pimpm's pre-check (the full step if it cuts the residual norm to a
    quarter, else
    l2's parabola: pimpm.line_search); frictionless and bonded pairs: the
    default bt (pimpm.presets.CONTACT_OPTIONS); none has a divergence test.
    A line search the input or the command line names is taken as it is."""
    full = presets.FULL_STEP_FIRST
    for kinds, line_search, full_first in (((), "bt", None), ({"tool"}, "basic", full),
                                           ({"frictional pair"}, "l2", None), ({"pair"}, "bt", None),
                                           ({"pair", "tool"}, "basic", full)):
        plan = resolve(problem={"contact": kinds})
        assert plan.options["snes_linesearch_type"] == line_search, kinds
        assert plan.full_step_first == full_first, kinds
        assert ("snes_divergence_tolerance" in plan.options) == bool(kinds), kinds
    plan = resolve(problem={"contact": {"pair"}}, petsc={"snes_linesearch_type": "l2"})
    assert plan.options["snes_linesearch_type"] == "l2" and plan.full_step_first is None
    plan = resolve(problem={"contact": {"tool"}}, petsc={"snes_linesearch_type": "basic"})
    assert plan.options["snes_linesearch_type"] == "basic" and plan.full_step_first is None
    assert resolve({"snes_linesearch_type": "l2"}, problem={"contact": {"tool"}}).full_step_first is None
    assert all(not key.startswith("pimpm_") for key in resolve(problem={"contact": {"tool"}}).options)


def test_the_command_line_chooses_the_preset_and_pimpm_switches():
    plan = resolve({"pimpm_preset": "gmres-gamg"})
    assert plan.preset == "gmres-gamg" and plan.iterative and plan.fallback and plan.near_null_space
    assert plan.options["fallback_pc_type"] == "cholesky"          # the direct fallback, symmetric
    assert not resolve({"pimpm_preset": "gmres-gamg", "pimpm_fallback": "0"}).fallback
    assert resolve({"pimpm_preset": "gmres-gamg", "pimpm_fallback": ""}).fallback   # a bare flag is true
    assert not resolve(preset="gmres-gamg", fallback=False).fallback
    plan = resolve({"pimpm_preset": "matrix-free"})
    assert plan.matrix_free and not plan.fallback and not plan.on_pattern and not plan.symmetric
    assert "pimpm_tangent" not in plan.options


def test_the_direct_solver_factorizes_the_free_dofs_unless_something_else_is_asked():
    assert resolve().free_dofs
    assert not resolve(free_dofs_only=False).free_dofs
    assert not resolve({"ksp_type": "gmres"}).free_dofs          # the command line's solver
    assert not resolve(petsc={"pc_type": "ilu"}).free_dofs
    assert not resolve({"snes_mf_operator": ""}).free_dofs
    assert resolve({"snes_mf_operator": ""}).mf_operator
    assert not resolve(problem={"coo": False}).free_dofs
    assert not resolve(preset="gmres-gamg").free_dofs             # iterative


def test_convergence_test_and_its_tolerances():
    assert resolve().convergence == ("petsc", None, None)
    gw = dict(SOLVER["convergence"], test="guilkey_weiss")
    assert resolve(convergence=gw).convergence == ("guilkey_weiss", 1e-6, 1e-12)
    plan = resolve({"pimpm_convergence_test": "guilkey_weiss", "pimpm_gw_energy_tol": "1e-9"})
    assert plan.convergence == ("guilkey_weiss", 1e-6, 1e-9)


@pytest.mark.parametrize("command_line, solver, problem, message", [
    ({"pimpm_preset": "lu"}, {}, {}, "-pimpm_preset lu: expected one of mumps, cg-gamg"),
    ({"pimpm_fallback": "maybe"}, {}, {}, "-pimpm_fallback maybe: expected true or false"),
    ({}, {"preset": "cg-gamg"}, {"symmetric": False}, "solver.preset = 'cg-gamg': expected a preset for non-symmetric"),
    ({"pimpm_preset": "cg-gamg"}, {}, {"symmetric": False}, "-pimpm_preset = 'cg-gamg'"),
    ({"pimpm_convergence_test": "energy"}, {}, {}, "-pimpm_convergence_test energy: expected petsc or guilkey_weiss"),
    ({"pimpm_convergence_test": "guilkey_weiss", "pimpm_gw_energy_tol": "small"}, {}, {},
     "-pimpm_gw_energy_tol small: expected a positive, finite number"),
])
def test_bad_settings_are_named_with_their_value(command_line, solver, problem, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        resolve(command_line, problem, **solver)


def test_factorization_reuse_and_the_linear_predictor_are_on_in_3d_unless_the_input_says():
    """``solver.reuse_factorization`` and ``solver.linear_predictor``: auto
    (the default) is on in 3D and off in 2D; true and false win; a step's
    factorization is reused only by the direct solve on the free dofs."""
    auto = {"reuse_factorization": "auto", "linear_predictor": "auto"}
    plan2, plan3 = resolve(**auto), resolve(problem={"dim": 3}, **auto)
    assert (plan2.reuse_factorization, plan2.linear_predictor) == (False, False)
    assert (plan3.reuse_factorization, plan3.linear_predictor) == (True, True)
    forced = resolve(reuse_factorization=True, linear_predictor=True)
    assert forced.reuse_factorization and forced.linear_predictor
    off = resolve(problem={"dim": 3}, reuse_factorization=False, linear_predictor=False)
    assert not off.reuse_factorization and not off.linear_predictor
    iterative = resolve({"pimpm_preset": "gmres-gamg"}, problem={"dim": 3}, **auto)
    assert not iterative.reuse_factorization and iterative.linear_predictor
    assert not resolve(problem={"dim": 3}, free_dofs_only=False, **auto).reuse_factorization


def test_the_fallback_factorizes_at_most_the_free_dofs_the_input_allows():
    """``solver.fallback_max_dofs``: auto is pimpm.presets.FALLBACK_MAX_DOFS
    by dimension; a number wins."""
    from pimpm.presets import FALLBACK_MAX_DOFS
    assert resolve(fallback_max_dofs="auto").fallback_max_dofs == FALLBACK_MAX_DOFS[2]
    assert resolve(problem={"dim": 3}, fallback_max_dofs="auto").fallback_max_dofs == FALLBACK_MAX_DOFS[3]
    assert resolve(problem={"dim": 3}, fallback_max_dofs=123).fallback_max_dofs == 123
