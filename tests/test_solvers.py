"""The solver stack: presets, the direct fallback, step cuts, Guilkey &
Weiss's convergence test, and option precedence (command line > YAML >
preset > defaults)."""
import copy
import re

import numpy as np
import petsc4py
petsc4py.init([])
import pytest
from mpi4py import MPI

from helpers import coarse_billet, read_history, run_pimpm, write_yaml
from pimpm.config import validate
from pimpm.simulation import Simulation


def billet_config(preset="mumps", petsc=None, convergence=None, end_time=0.04):
    raw = coarse_billet("quasi_static")
    raw["time"]["end_time"] = end_time
    raw["solver"] = {"preset": preset, "petsc": petsc or {}}
    if convergence:
        raw["solver"]["convergence"] = convergence
    return validate(raw)


def run_steps(config, steps):
    sim = Simulation(config, MPI.COMM_WORLD)
    infos = [sim.advance(config["time"]["dt"]) for _ in range(steps)]
    return sim, infos


def bulge(sim):
    p = sim.particles
    on_plane = p["x0"][:, 1] == p["x0"][:, 1].min()
    i = np.flatnonzero(on_plane)[np.argmax(p["x0"][on_plane, 0])]
    return p["x"][i, 0] - p["x0"][i, 0]


def test_every_preset_gives_the_same_billet():
    """2 steps (10% compression) of the 1 cm billet with every preset (the
    matrix-free ones evaluate the residual ~500 times a step)."""
    results = {}
    for preset in ("mumps", "cg-gamg", "gmres-gamg", "gmres-hypre", "jfnk", "matrix-free"):
        sim, infos = run_steps(billet_config(preset, end_time=0.02), 2)
        results[preset] = bulge(sim), infos
        assert all(info["newton_iterations"] <= 10 for info in infos), preset
        sim.solver.destroy()
    reference = results["mumps"][0]
    assert reference > 1.0
    for preset, (value, infos) in results.items():
        assert abs(value - reference) <= 1e-6 * abs(reference), preset
        if preset != "mumps":
            assert sum(i["linear_iterations"] for i in infos) > sum(i["newton_iterations"] for i in infos)


def test_failing_iterative_solve_falls_back_to_direct():
    """-ksp_max_it 1 makes every CG solve fail; each Newton step is then
    solved by MUMPS (G&W 3.3) and the step converges as with the direct solver."""
    sim, infos = run_steps(billet_config("cg-gamg", petsc={"ksp_max_it": 1}), 2)
    direct, direct_infos = run_steps(billet_config("mumps"), 2)
    for info, reference in zip(infos, direct_infos):
        assert info["linear_fallbacks"] == info["newton_iterations"] > 0
        assert info["newton_iterations"] == reference["newton_iterations"]
    assert abs(bulge(sim) - bulge(direct)) <= 1e-8 * abs(bulge(direct))
    # without the fallback the same settings cannot converge
    raw = copy.deepcopy(billet_config("cg-gamg", petsc={"ksp_max_it": 1}))
    raw["solver"]["fallback"] = False
    sim_nofb = Simulation(raw, MPI.COMM_WORLD)
    with pytest.raises(Exception, match="did not converge"):
        sim_nofb.advance(raw["time"]["dt"])
    for s in (sim, direct, sim_nofb):
        s.solver.destroy()


def test_guilkey_weiss_criteria_stop_newton_where_defined():
    eps_d, eps_e = 1e-4, 1e-8
    config = billet_config(convergence={"test": "guilkey_weiss", "displacement_tolerance": eps_d,
                                        "energy_tolerance": eps_e})
    sim = Simulation(config, MPI.COMM_WORLD)
    test = sim.solver.gw_test
    for _ in range(3):
        info = sim.advance(config["time"]["dt"])
        ratios = test.ratios
        assert test.converged and len(ratios) == info["newton_iterations"]
        d_last, e_last = ratios[-1]
        assert d_last < eps_d and e_last < eps_e                 # eq. 13 holds at the end ...
        assert all(d >= eps_d or e >= eps_e for d, e in ratios[:-1])   # ... and not before
    sim.solver.destroy()


def test_too_large_step_is_cut_and_retried(tmp_path):
    """A platen moving 4 cells per step fails; the step is cut, retried, and
    the run reaches its end time with the cuts in the history."""
    raw = coarse_billet("quasi_static", directory="out")
    raw["time"].update(dt=0.08, end_time=0.08, max_cuts=4)
    raw["solver"] = {"petsc": {"snes_max_it": 8}}
    write_yaml(tmp_path / "big.yaml", raw)
    proc = run_pimpm(None, ["big.yaml"], cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "cutting the step" in proc.stdout
    history = read_history(tmp_path / "out" / "history.csv")
    assert history["step_cuts"].sum() >= 1
    assert history["time"][-1] == pytest.approx(0.08, rel=1e-12)
    assert history["dt"].min() < 0.08


def test_ramp_starts_small_and_grows_to_dt(tmp_path):
    raw = coarse_billet("quasi_static", directory="out")
    raw["time"].update(dt=0.01, end_time=0.04, dt_initial=0.0025, ramp_factor=2.0)
    write_yaml(tmp_path / "ramp.yaml", raw)
    proc = run_pimpm(None, ["ramp.yaml"], cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    dts = read_history(tmp_path / "out" / "history.csv")["dt"]
    assert dts[0] == pytest.approx(0.0025) and dts[1] == pytest.approx(0.005)
    assert dts[2] == pytest.approx(0.01)
    assert np.sum(dts) == pytest.approx(0.04, rel=1e-12)


def test_lagrangian_limit_cuts_steps(tmp_path):
    """time.max_particle_displacement = 0.2 cells: the platen moves half a
    cell per step, so steps are cut until no particle moves more than 0.2 cells."""
    raw = coarse_billet("quasi_static", directory="out")
    raw["time"].update(end_time=0.02, max_particle_displacement=0.2, max_cuts=6)
    write_yaml(tmp_path / "lim.yaml", raw)
    proc = run_pimpm(None, ["lim.yaml"], cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "time.max_particle_displacement" in proc.stdout
    dts = read_history(tmp_path / "out" / "history.csv")["dt"]
    assert dts.max() <= 0.01 * 0.2 / 0.5 + 1e-15


def test_command_line_beats_yaml_and_unused_options_are_reported(tmp_path):
    raw = coarse_billet("quasi_static", directory="out")
    raw["time"]["end_time"] = 0.01
    raw["solver"] = {"preset": "cg-gamg", "petsc": {"snes_linesearch_type": "basic", "snes_rtol": 1e-9}}
    write_yaml(tmp_path / "opts.yaml", raw)
    proc = run_pimpm(None, ["opts.yaml", "-pimpm_preset", "mumps", "-snes_linesearch_type", "l2",
                            "-snes_view", "-options_left", "-no_such_option", "3"], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout
    assert "preset mumps" in out                                  # pimpm option
    assert re.search(r"SNESLineSearch Object.*\n\s+type: l2", out)  # SNES option
    assert "relative=1e-09" in out                                # YAML option kept (not overridden)
    # KSP/PC of the preset; the neo-Hookean tangent is symmetric: LDL^T
    assert "type: preonly" in out and "type: cholesky" in out
    assert re.search(r"Option left: name:-no_such_option value: 3", out)
    assert "Option left: name:-snes_rtol" not in out              # program options are not 'left'


def test_matrix_free_axisymmetric_plastic_matches_assembled():
    """The matrix-free product carries the axisymmetric hoop terms: four
    plastic steps of the upsetting problem (2 mm cells) take the same Newton
    iterations and end at the same particle positions as with MUMPS."""
    from helpers import coarse_upsetting
    raw = coarse_upsetting()
    raw["time"] = {"integrator": "quasi_static", "end_time": 2e-3, "dt": 5e-4}
    results = {}
    for preset in ("mumps", "matrix-free"):
        raw["solver"] = {"preset": preset}
        sim, infos = run_steps(validate(copy.deepcopy(raw)), 4)
        results[preset] = (sim.particles["x"].copy(), [i["newton_iterations"] for i in infos])
        assert sim.particles["h_eq_plastic_strain"].max() > 0.01
        sim.solver.destroy()
    (x_direct, its_direct), (x_free, its_free) = results["mumps"], results["matrix-free"]
    assert its_free == its_direct
    np.testing.assert_allclose(x_free, x_direct, rtol=0, atol=1e-9)


def _iterative_ksp(sim):
    return sim.solver.linear_ksp()


def _smoother_max_it(ksp):
    pc = ksp.getPC()
    assert pc.getMGLevels() >= 2
    return pc.getMGSmoother(1).getTolerances()[3]


@pytest.mark.parametrize("source", ["preset", "yaml", "command line"])
def test_options_are_in_force_for_the_whole_solve(source):
    """Options read at first use (GAMG's level smoothers and MUMPS's ICNTL
    are read in PCSetUp, during the first solve) reach the live objects, from
    the preset, the YAML and the command line (the database), in that order
    of precedence."""
    from petsc4py import PETSc
    db = PETSc.Options()
    expected = {"preset": (3, 1e-8, None), "yaml": (4, 1e-7, 35), "command line": (5, 1e-6, 40)}[source]
    yaml_gamg = {"mg_levels_ksp_max_it": 4, "ksp_rtol": 1e-7} if source != "preset" else {}
    yaml_mumps = {"mat_mumps_icntl_14": 35} if source != "preset" else {}
    command_line = {"mg_levels_ksp_max_it": "5", "ksp_rtol": "1e-6", "mat_mumps_icntl_14": "40"}
    if source == "command line":
        for key, value in command_line.items():
            db.setValue(key, value)
    try:
        gamg, _ = run_steps(billet_config("cg-gamg", petsc=yaml_gamg), 1)
        ksp = _iterative_ksp(gamg)
        assert _smoother_max_it(ksp) == expected[0]
        assert ksp.getTolerances()[0] == pytest.approx(expected[1], rel=1e-12)
        gamg.solver.destroy()
        direct, _ = run_steps(billet_config("mumps", petsc=yaml_mumps), 1)
        factor = direct.solver.linear_ksp().getPC().getFactorMatrix()
        if expected[2] is None:
            assert factor.getMumpsIcntl(14) not in (35, 40)      # MUMPS's own default
        else:
            assert factor.getMumpsIcntl(14) == expected[2]
        direct.solver.destroy()
    finally:
        for key in command_line:
            if db.hasName(key):
                db.delValue(key)
    for key in ("mg_levels_ksp_max_it", "ksp_rtol", "mat_mumps_icntl_14"):
        assert not db.hasName(key)          # program options do not leak out of the solve


def test_symmetric_tangent_is_factorized_by_ldlt_and_gives_the_lu_answer():
    """The neo-Hookean billet's tangent is symmetric (tests/mpi/jacobian_check.py
    measures it): MUMPS factorizes it by LDL^T unless the options say lu, and
    the two give the same steps. A finite-strain J2 tangent is not symmetric:
    LU."""
    ldlt, ldlt_infos = run_steps(billet_config("mumps"), 3)
    lu, lu_infos = run_steps(billet_config("mumps", petsc={"pc_type": "lu"}), 3)
    assert ldlt.solver.linear_ksp().getPC().getType() == "cholesky"
    assert lu.solver.linear_ksp().getPC().getType() == "lu"
    assert [i["newton_iterations"] for i in ldlt_infos] == [i["newton_iterations"] for i in lu_infos]
    assert abs(bulge(ldlt) - bulge(lu)) <= 1e-10 * abs(bulge(lu))
    for s in (ldlt, lu):
        s.solver.destroy()
    from helpers import coarse_upsetting
    plastic = Simulation(validate(coarse_upsetting()), MPI.COMM_WORLD)
    assert not plastic.problem.symmetric
    assert plastic.solver.linear_ksp().getPC().getType() == "lu"
    plastic.solver.destroy()


def _coupled_rows(A):
    """Global number of rows of ``A`` with a nonzero off-diagonal entry."""
    start, end = A.getOwnershipRange()
    indptr, columns, values = A.getValuesCSR()
    rows = np.repeat(np.arange(start, end), np.diff(indptr))
    return MPI.COMM_WORLD.allreduce(len(np.unique(rows[(columns != rows) & (values != 0.0)])))


def test_direct_solver_factorizes_only_the_free_dofs():
    """The Newton matrix keeps prescribed and massless dofs as rows holding
    only their diagonal; the direct solver factorizes the others alone
    (pimpm.linear.FreeDofsKSP) and solves those rows by division. Its matrix
    has exactly as many rows as the whole matrix has coupled rows (counted
    on the assembled matrix, as PETSc's PCREDISTRIBUTE counts them), far
    fewer than the grid's dofs, and the billet takes the same Newton steps
    to the same answer as when MUMPS factorizes the whole matrix
    (-pimpm_free_dofs_only 0)."""
    from petsc4py import PETSc
    db = PETSc.Options()
    free, free_infos = run_steps(billet_config("mumps"), 3)
    solver = free.solver
    assert solver.free_dofs is not None and "on the free dofs" in solver.describe()
    factorized = solver.linear_ksp().getOperators()[0]
    n_factorized, n_all = factorized.getSize()[0], solver.J.getSize()[0]
    whole = solver.whole_jacobian()        # (Newton's matrix is the free dofs' operator)
    assert whole is not solver.J
    assert n_factorized == _coupled_rows(whole)
    whole.destroy()
    assert n_factorized < 0.8 * n_all
    assert factorized.getSize()[0] == MPI.COMM_WORLD.allreduce(int(np.count_nonzero(solver.free_dofs.free)))
    db.setValue("pimpm_free_dofs_only", "0")
    try:
        whole, whole_infos = run_steps(billet_config("mumps"), 3)
    finally:
        db.delValue("pimpm_free_dofs_only")
    assert whole.solver.free_dofs is None
    assert whole.solver.linear_ksp().getOperators()[0].getSize()[0] == n_all
    assert [i["newton_iterations"] for i in free_infos] == [i["newton_iterations"] for i in whole_infos]
    for a, b in zip(free_infos, whole_infos):
        np.testing.assert_allclose(a["residual_history"], b["residual_history"], rtol=1e-7, atol=1e-14)
    assert abs(bulge(free) - bulge(whole)) <= 1e-12 * abs(bulge(whole))
    np.testing.assert_allclose(free.particles["x"], whole.particles["x"], rtol=0, atol=1e-12)
    for s in (free, whole):
        s.solver.destroy()


def test_the_fallback_factorizes_the_free_dofs_or_cuts_the_step_when_they_are_too_many():
    """The direct fallback solves the free dofs only (the prescribed rows by
    their diagonal): with every GMRES solve failing it gives the direct
    solver's steps; with fewer solver.fallback_max_dofs than free dofs it is
    not tried, and Newton fails saying so (the step is then cut)."""
    sim, infos = run_steps(billet_config("gmres-gamg", petsc={"ksp_max_it": 1}), 2)
    direct, direct_infos = run_steps(billet_config("mumps"), 2)
    for info, reference in zip(infos, direct_infos):
        assert info["linear_fallbacks"] == info["newton_iterations"] == reference["newton_iterations"]
    assert abs(bulge(sim) - bulge(direct)) <= 1e-10 * abs(bulge(direct))
    fallback = sim.solver.fallback
    assert fallback.free is not None and 0 < np.count_nonzero(fallback.free) < len(fallback.free)
    raw = copy.deepcopy(billet_config("gmres-gamg", petsc={"ksp_max_it": 1}))
    raw["solver"]["fallback_max_dofs"] = 10
    capped = Simulation(raw, MPI.COMM_WORLD)
    with pytest.raises(Exception, match="the direct fallback was not tried: more than "
                                        "solver.fallback_max_dofs = 10 free dofs"):
        capped.advance(raw["time"]["dt"])
    assert capped.solver.fallback.fallbacks == 0 and capped.solver.fallback.skipped > 0
    for s in (sim, direct, capped):
        s.solver.destroy()


def test_iterative_and_fallback_solvers_keep_the_whole_matrix():
    """Only a direct solver (preonly + lu/cholesky) gets the free-dof matrix:
    GMRES + GAMG with the fallback, and -pc_type lu under an iterative KSP,
    solve the whole one (the fallback extracts its free dofs when it must)."""
    gamg, _ = run_steps(billet_config("gmres-gamg"), 1)
    assert gamg.solver.free_dofs is None and gamg.solver.fallback is not None
    gamg.solver.destroy()
    gmres_lu, _ = run_steps(billet_config("mumps", petsc={"ksp_type": "gmres"}), 1)
    assert gmres_lu.solver.free_dofs is None
    assert gmres_lu.solver.linear_ksp().getType() == "gmres"
    gmres_lu.solver.destroy()


def test_ksp_view_options_show_the_ksp_that_solves(tmp_path):
    """-ksp_view and -ksp_view_mat act on the KSP that solves, inside pimpm's
    python KSP, at every Newton iteration of every step (the free-dof solver
    resets only its PC between steps: KSPReset would drop the viewers): a
    one-step billet prints the direct solver and saves the free dofs'
    matrices (fewer rows than the grid has dofs); with the GMRES + GAMG
    preset, the iterative solver and the whole matrix."""
    from petsc4py import PETSc
    raw = coarse_billet("quasi_static")
    raw["time"]["end_time"] = raw["time"]["dt"]
    write_yaml(tmp_path / "input.yaml", raw)
    grid_dofs = 2 * (raw["grid"]["cells"][0] + 1) * (raw["grid"]["cells"][1] + 1)
    for preset, ksp_type in (("mumps", "preonly"), ("gmres-gamg", "gmres")):
        proc = run_pimpm(None, ["input.yaml", "--overwrite", "-pimpm_preset", preset, "-ksp_view",
                                "-ksp_view_mat", f"binary:{preset}.bin"], cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
        newton = int(read_history(tmp_path / "out" / "history.csv")["newton_iterations"][0])
        views = re.findall(r"KSP Object: 1 MPI process\n\s+type: (\S+)", proc.stdout)
        assert views.count(ksp_type) == newton, views
        viewer = PETSc.Viewer().createBinary(str(tmp_path / f"{preset}.bin"), "r", comm=PETSc.COMM_SELF)
        A = PETSc.Mat().create(comm=PETSc.COMM_SELF)
        A.setType(PETSc.Mat.Type.AIJ)
        A.load(viewer)
        rows = A.getSize()[0]
        assert (rows < 0.8 * grid_dofs) if preset == "mumps" else (rows == grid_dofs), rows
        A.destroy()
        viewer.destroy()


def upsetting_3d_config(dt, end_time, **solver):
    """inputs/upsetting_3d.yaml (2 mm cells) with the step and solver changed,
    the platen bonded (it prescribes its motion on the nodes, what the
    linearized start responds to; the input's is tied)."""
    import os
    import yaml
    from helpers import ROOT
    with open(os.path.join(ROOT, "inputs", "upsetting_3d.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["bodies"][1]["contact"] = "bonded"
    raw["time"].update(dt=dt, end_time=end_time)
    raw["solver"] = dict(raw.get("solver", {}), **solver)
    return validate(raw)


def test_reused_factorization_and_linear_predictor_give_the_same_3d_steps():
    """The 3D upsetting's first three steps with the 3D defaults (one
    factorization per step, GMRES on the later Newton systems; the first
    step started from the linearized response to the platen's motion)
    against a factorization at every Newton iteration from the plain
    predictor: the same forces and positions to Newton's tolerance; the
    reused factorization preconditions GMRES (more than one linear
    iteration a Newton iteration, not one factorization each); the
    linearized start begins step 1 much closer to the answer and takes
    fewer Newton iterations."""
    fast, fast_infos = run_steps(upsetting_3d_config(2.5e-4, 7.5e-4), 3)
    plain, plain_infos = run_steps(upsetting_3d_config(2.5e-4, 7.5e-4, reuse_factorization=False,
                                                       linear_predictor=False), 3)
    assert fast.solver.plan.reuse_factorization and fast.solver.plan.linear_predictor
    assert fast.solver.free_dofs.lagged is not None and plain.solver.free_dofs.lagged is None
    assert "factorized once per step" in fast.solver.describe()
    for a, b in zip(fast_infos, plain_infos):
        assert a["dt"] == b["dt"] == 2.5e-4
        np.testing.assert_allclose(a["forces"]["platen"], b["forces"]["platen"], rtol=1e-7)
        assert a["linear_iterations"] > a["newton_iterations"]
        assert b["linear_iterations"] == b["newton_iterations"]
    np.testing.assert_allclose(fast.particles["x"], plain.particles["x"], rtol=0, atol=1e-8)   # mm
    assert fast_infos[0]["residual_initial"] < 0.2 * plain_infos[0]["residual_initial"]
    assert fast_infos[0]["newton_iterations"] < plain_infos[0]["newton_iterations"]
    for s in (fast, plain):
        s.solver.destroy()


def test_linear_predictor_is_the_answer_of_a_linear_elastic_step():
    """A platen motion of 1e-6 mm keeps the cylinder linear elastic: the
    linearized response to it is then the step's answer, so Newton starts
    from a residual many orders of magnitude below that of the plain
    predictor (the whole motion in the cells under the platen)."""
    initial = {}
    for on in (True, False):
        sim, infos = run_steps(upsetting_3d_config(1e-9, 1e-9, linear_predictor=on), 1)
        initial[on] = infos[0]["residual_initial"]
        sim.solver.destroy()
    assert initial[True] < 1e-5 * initial[False]


def _reused_factorization_solver(dense, rng):
    """A python KSP with FreeDofsKSP's reused factorization (PETSc's own LU
    inside, every dof free) on a dense matrix made from ``dense``, and a
    random right-hand side and a solution vector: (outer, context, A, b, x)."""
    from petsc4py import PETSc
    from pimpm.linear import FreeDofsKSP
    n = dense.shape[0]
    A = PETSc.Mat().createDense((n, n), array=dense.copy(), comm=PETSc.COMM_SELF)
    A.assemble()
    outer = PETSc.KSP().create(comm=PETSc.COMM_SELF)
    outer.setType(PETSc.KSP.Type.PYTHON)
    context = FreeDofsKSP(reuse_factorization=True)
    outer.setPythonContext(context)
    outer.getPC().setType(PETSc.PC.Type.NONE)
    context.setFromOptions(outer)
    context.inner.setType(PETSc.KSP.Type.PREONLY)
    context.inner.getPC().setType(PETSc.PC.Type.LU)
    b = PETSc.Vec().createSeq(n)
    b.setArray(rng.standard_normal(n))
    x = b.duplicate()
    context.set_matrix(A, np.ones(n, dtype=bool))
    return outer, context, A, b, x


def _solve_with(outer, A, dense, b, x):
    """Solve with ``A`` holding ``dense``: the answer to the lagged solves'
    tolerance, and the iterations."""
    from pimpm.linear import LAGGED_RTOL
    n = dense.shape[0]
    A.setValues(range(n), range(n), dense.ravel())
    A.assemble()
    outer.setOperators(A, A)
    outer.solve(b, x)
    assert outer.getConvergedReason() > 0
    exact = np.linalg.solve(dense, b.getArray())
    assert np.linalg.norm(x.getArray() - exact) <= 1e3 * LAGGED_RTOL * np.linalg.norm(exact)
    return outer.getIterationNumber()


def test_lagged_solves_factorize_anew_when_gmres_stalls():
    """FreeDofsKSP with reuse: the first solve of a step factorizes, the next
    ones run GMRES preconditioned by that factorization to the true-residual
    tolerance, and a matrix too far from the factorized one is factorized
    anew (within LAGGED_MAX_IT iterations or not at all)."""
    n = 200
    rng = np.random.default_rng(3)

    def matrix(shift, noise):
        dense = np.diag(np.full(n, 4.0 + shift)) - np.eye(n, k=1) - np.eye(n, k=-1)
        return dense + noise * rng.standard_normal((n, n))
    outer, context, A, b, x = _reused_factorization_solver(matrix(0.0, 0.0), rng)
    iterations = [_solve_with(outer, A, matrix(shift, noise), b, x)
                  for shift, noise in ((0.0, 0.0), (0.05, 0.002), (0.0, 1.0))]
    assert iterations[0] == 1 and 1 < iterations[1] < 30      # factorized, then lagged
    assert context.refactorizations == 1                      # the far matrix: factorized anew
    context.release()
    for obj in (outer, A, b, x):
        obj.destroy()


def test_a_factorization_out_of_mumps_work_space_is_repeated_with_more():
    """MUMPS sizes its work space at analysis; a nearly singular tangent
    that pivots late needs more (INFOG(1) = -9: the 0.5 mm 3D upsetting's
    step 24, every cut alike). FreeDofsKSP factorizes again with twice the
    space (ICNTL(14)), keeps it for the run, and leaves the options
    database as it was. A matrix with a tiny diagonal and ICNTL(14) = 0
    reproduces the failure."""
    from petsc4py import PETSc
    from pimpm.linear import FreeDofsKSP
    n = 300
    rng = np.random.default_rng(0)
    dense = np.zeros((n, n))
    for i in range(n):
        for j in rng.choice(n, 8, replace=False):
            if i != j:
                dense[i, j], dense[j, i] = rng.standard_normal(2)
        dense[i, i] = 1e-12
    A = PETSc.Mat().createAIJ((n, n), nnz=40, comm=PETSc.COMM_SELF)
    rows, cols = np.nonzero(dense)
    for i, j in zip(rows, cols):
        A[i, j] = dense[i, j]
    A.assemble()
    db = PETSc.Options()
    db.setValue("mat_mumps_icntl_14", "0")
    try:
        outer = PETSc.KSP().create(comm=PETSc.COMM_SELF)
        outer.setType(PETSc.KSP.Type.PYTHON)
        context = FreeDofsKSP()
        outer.setPythonContext(context)
        outer.getPC().setType(PETSc.PC.Type.NONE)
        context.setFromOptions(outer)
        context.inner.setType(PETSc.KSP.Type.PREONLY)
        context.inner.getPC().setType(PETSc.PC.Type.LU)
        context.inner.getPC().setFactorSolverType("mumps")
        b = PETSc.Vec().createSeq(n)
        b.setArray(rng.standard_normal(n))
        x = b.duplicate()
        context.set_matrix(A, np.ones(n, dtype=bool))
        outer.setOperators(A, A)
        outer.solve(b, x)
        assert outer.getConvergedReason() > 0
        np.testing.assert_allclose(dense @ x.getArray(), b.getArray(), atol=1e-8 * np.abs(b.getArray()).max())
        assert context.workspace_retries == 1 and context.workspace == 40
        assert db.getString("mat_mumps_icntl_14") == "0"
        context.release()
        for obj in (outer, b, x):
            obj.destroy()
    finally:
        db.delValue("mat_mumps_icntl_14")
        A.destroy()


def test_a_lagged_solve_that_needed_many_iterations_has_the_next_system_factorized(monkeypatch):
    """FreeDofsKSP with reuse: a lagged GMRES solve that converged but needed
    LAGGED_REFRESH_IT iterations or more marks the factorization stale, and
    the next system is factorized anew (one iteration, no failed GMRES
    counted as a refactorization) instead of GMRES running out of iterations
    on it; a lagged solve below the threshold keeps the factorization."""
    import pimpm.linear as linear
    n = 200
    rng = np.random.default_rng(5)
    dense0 = np.diag(np.full(n, 4.0)) - np.eye(n, k=1) - np.eye(n, k=-1)
    outer, context, A, b, x = _reused_factorization_solver(dense0, rng)

    def solve(noise):
        return _solve_with(outer, A, dense0 + noise * rng.standard_normal((n, n)), b, x)

    first = solve(0.0)
    lagged = solve(0.01)
    assert first == 1 and 1 < lagged < linear.LAGGED_MAX_IT
    monkeypatch.setattr(linear, "LAGGED_REFRESH_IT", linear.LAGGED_MAX_IT)
    assert solve(0.01) > 1 and not context.stale              # below the threshold: still lagged
    monkeypatch.setattr(linear, "LAGGED_REFRESH_IT", 2)
    assert solve(0.01) > 1 and context.stale                  # at or above it: stale
    assert solve(0.01) == 1 and not context.stale              # so this one is factorized anew
    assert solve(0.01) > 1                                     # and the next one lagged again
    assert context.refactorizations == 0
    context.release()
    for obj in (outer, A, b, x):
        obj.destroy()


def test_newton_stopped_by_a_short_step_with_the_residual_still_large_has_failed(tmp_path):
    """PETSc stops Newton when a step is shorter than snes_stol times the
    iterate, whatever the residual; pimpm counts that as converged only if
    the residual has fallen to 1e-4 of its start (pimpm.solver.
    SNORM_RESIDUAL_FRACTION), and otherwise cuts the step. Here snes_stol
    0.3 stops the billet's Newton after one or two iterations."""
    config = coarse_billet(directory=str(tmp_path / "out"))
    config["time"]["end_time"] = 2 * config["time"]["dt"]
    proc = run_pimpm(None, [write_yaml(tmp_path / "billet.yaml", config), "-snes_stol", "0.3"])
    assert "fell below snes_stol with the residual still" in proc.stdout + proc.stderr, proc.stdout + proc.stderr
    rows = read_history(tmp_path / "out" / "history.csv")
    assert len(rows) and np.all(rows["residual_final"] <= 1e-4 * rows["residual_initial"] + 1e-12)


def test_the_contact_line_search_monitor_follows_the_input_too(tmp_path):
    """-snes_linesearch_monitor in the YAML's solver.petsc reaches pimpm's
    line search of rigid tools (pimpm.line_search), not only PETSc's."""
    config = coarse_billet(directory=str(tmp_path / "out"))
    config["bodies"][1].update(contact="friction", friction_coefficient=0.3)
    config["time"]["end_time"] = config["time"]["dt"]
    config["solver"] = {"petsc": {"snes_linesearch_monitor": ""}}
    proc = run_pimpm(None, [write_yaml(tmp_path / "billet.yaml", config)])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Line search (pimpm, full step first)" in proc.stdout, proc.stdout


@pytest.mark.parametrize("fallback", [False, True])
def test_geometric_multigrid_is_set_up_anew_for_each_steps_pattern(fallback):
    """PCMG (Galerkin coarse operators on the DMDA's hierarchy) keeps what it
    built from the first matrix it was set up with, and each step's matrix
    has a new nonzero pattern: the PC is reset when the step's matrix is made
    (pimpm.linear.RESET_ON_NEW_PATTERN). The later steps then take about the
    GMRES iterations of the first (without the reset, 10 times as many on the
    0.5 cm billet), with the direct fallback too, whose iterative KSP gets
    the grid's DMDA for the coarsening (without it PETSc crashed)."""
    petsc = {"pc_type": "mg", "pc_mg_levels": "2", "pc_mg_galerkin": "both"}
    config = billet_config("gmres-gamg", petsc=petsc, end_time=0.03)
    config["solver"]["fallback"] = fallback
    sim, infos = run_steps(config, 3)
    per_newton = [info["linear_iterations"] / info["newton_iterations"] for info in infos]
    assert all(info["linear_fallbacks"] == 0 and info["dt"] == 0.01 for info in infos)   # no fallback, no cut
    assert per_newton[0] < 30
    assert max(per_newton[1:]) < 2.0 * per_newton[0], per_newton
    value = bulge(sim)
    sim.solver.destroy()
    direct, _ = run_steps(billet_config(end_time=0.03), 3)
    assert abs(value - bulge(direct)) <= 1e-6 * abs(bulge(direct))
    direct.solver.destroy()
