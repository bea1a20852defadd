"""The contact line search (pimpm.line_search.FullStepFirst): the full
Newton step when it at least halves the residual norm, at the cost of one
residual; otherwise the minimum of l2's parabola, as PETSc's l2 finds it."""
import sys

import numpy as np
import petsc4py

petsc4py.init(sys.argv[:1])
from petsc4py import PETSc  # noqa: E402

from pimpm.line_search import LAMBDA_MAX, FullStepFirst, l2_step  # noqa: E402


def test_the_fitted_step_is_l2s():
    # |F(lambda)| = |1 - lambda| |F(0)|: a linear residual, the minimum at the full step
    assert l2_step(1.0, 0.5, 0.0) == 1.0
    # |F|^2 = (lambda - 0.3)^2 + 0.01: a parabola, its minimum
    f = lambda lam: np.sqrt((lam - 0.3) ** 2 + 0.01)  # noqa: E731
    assert abs(l2_step(f(0.0), f(0.5), f(1.0)) - 0.3) < 1e-12
    # a minimum beyond the bound is clipped
    f = lambda lam: np.sqrt((lam - 5.0) ** 2 + 1.0)  # noqa: E731
    assert l2_step(f(0.0), f(0.5), f(1.0)) == LAMBDA_MAX
    # concave: downhill from the full step by E'(1) / |E''| (PETSc's l2 printed 1.19312 here)
    assert abs(l2_step(1.47113, 1.55524, 1.56358) - 1.19312) < 1e-4


def solve(residual, jacobian, x0, line_search, converge=True, **options):
    """Newton with PETSc on F(x) = residual(x) (componentwise, n = len(x0)),
    the line search ``line_search`` ("full-first" for FullStepFirst);
    returns (solution, iterations, residual evaluations, FullStepFirst or None)."""
    n = len(x0)
    snes = PETSc.SNES().create(comm=PETSc.COMM_SELF)
    X, R = PETSc.Vec().createSeq(n), PETSc.Vec().createSeq(n)
    J = PETSc.Mat().createAIJ([n, n], nnz=1, comm=PETSc.COMM_SELF)
    calls = [0]

    def form_residual(snes, x, r):
        calls[0] += 1
        r.setArray(residual(x.getArray(readonly=True)))

    def form_jacobian(snes, x, A, P):
        P.zeroEntries()
        P.setDiagonal(PETSc.Vec().createWithArray(jacobian(x.getArray(readonly=True))))
        P.assemble()

    snes.setFunction(form_residual, R)
    snes.setJacobian(form_jacobian, J)
    snes.getKSP().setType("preonly")
    snes.getKSP().getPC().setType("lu")
    db = PETSc.Options()
    db["snes_linesearch_type"] = "basic" if line_search == "full-first" else line_search
    for key, value in {"snes_rtol": 1e-12, "snes_atol": 1e-14, "snes_max_it": 50, **options}.items():
        db[key] = value
    snes.setFromOptions()
    pre = FullStepFirst(snes, form_residual, R, 0.5) if line_search == "full-first" else None
    for key in ["snes_linesearch_type", "snes_rtol", "snes_atol", "snes_max_it", *options]:
        db.delValue(key)
    X.setArray(x0)
    snes.solve(None, X)
    assert snes.getConvergedReason() > 0 or not converge, snes.getConvergedReason()
    out = X.getArray().copy(), snes.getIterationNumber(), calls[0], pre
    if pre is not None:
        pre.destroy()
    for obj in (snes, X, R, J):
        obj.destroy()
    return out


def test_a_newton_step_that_halves_the_residual_is_taken_with_one_residual():
    """Newton on x^3 + x = 2 near its root converges quadratically: every
    step is the full one, each with one residual (l2 takes three)."""
    f, df = (lambda x: x ** 3 + x - 2.0), (lambda x: 3 * x ** 2 + 1.0)
    x0 = np.array([1.3, 0.8, 1.1])
    x, its, calls, pre = solve(f, df, x0, "full-first")
    assert np.allclose(x, 1.0, atol=1e-12)
    assert pre.full_steps == its and pre.fitted == 0
    assert calls == its + 1                 # the kept step's residual is not evaluated again
    x_l2, its_l2, calls_l2, _ = solve(f, df, x0, "l2")
    assert calls_l2 == 3 * its_l2 + 1 and calls < calls_l2
    x_basic, its_basic, _, _ = solve(f, df, x0, "basic")
    assert np.array_equal(x, x_basic) and its_basic == its       # the same iterates as the full steps


def test_a_step_that_does_not_halve_the_residual_is_fitted_as_l2_fits_it():
    """Newton on arctan(x) = 0 from 1.5 overshoots farther at every full
    step; the parabola pulls it back, on the same iterates as PETSc's l2."""
    f, df = np.arctan, (lambda x: 1.0 / (1.0 + x ** 2))
    x0 = np.array([1.5])
    x, its, calls, pre = solve(f, df, x0, "full-first", snes_linesearch_max_it=1)
    assert abs(x[0]) < 1e-12 and pre.fitted >= 1 and pre.full_steps >= 1
    x_l2, its_l2, _, _ = solve(f, df, x0, "l2")
    assert its <= its_l2 and abs(x_l2[0]) < 1e-12
    # the first step (fitted) lands where l2's does
    first = solve(f, df, x0, "full-first", converge=False, snes_max_it=1)
    first_l2 = solve(f, df, x0, "l2", converge=False, snes_max_it=1)
    assert first[3].fitted == 1 and abs(first[0][0] - first_l2[0][0]) < 1e-14 * abs(x0[0])


def test_the_line_search_monitor_says_what_was_kept(capfd):
    """-snes_linesearch_monitor: a line per Newton iteration, full step or l2's."""
    solve(np.arctan, lambda x: 1.0 / (1.0 + x ** 2), np.array([1.5]), "full-first", snes_linesearch_monitor="")
    out = capfd.readouterr().out
    assert "full step kept" in out and "l2's lambda" in out, out
