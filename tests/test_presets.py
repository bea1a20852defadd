"""Solver presets are data (pimpm/presets.py): what each implies is derived
from its options, and the input schema's names are the presets' own."""
from pimpm import presets
from pimpm.config.schema import SOLVER_PRESETS


def test_what_a_preset_implies_is_derived_from_its_options():
    derived = {name: (presets.iterative(o), presets.needs_symmetric_tangent(o), presets.matrix_free(o))
               for name, o in presets.PRESETS.items()}
    assert derived == {"mumps": (False, False, False), "cg-gamg": (True, True, False),
                       "gmres-gamg": (True, False, False), "jfnk": (True, False, False),
                       "matrix-free": (True, False, True)}
    assert presets.iterative({}) is False          # PETSc's KSP default here is preonly


def test_pimpm_settings_stay_out_of_the_petsc_options_and_names_are_shared():
    options = presets.petsc_options(presets.PRESETS["matrix-free"])
    assert "pimpm_tangent" not in options and options["pc_type"] == "jacobi"
    assert SOLVER_PRESETS == tuple(presets.PRESETS)
