"""Jacobian and transfer checks run under mpiexec on 1, 2 and 3 ranks."""
import re

import pytest

from helpers import HERE, MPIEXEC, BatchedChecks, run_mpi

pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")


JACOBIAN_CASES = [(*case, "default") for case in [
    (1, "quasi_static", "2d", "linear", "elastic"), (1, "newmark", "2d", "linear", "elastic"),
    (2, "quasi_static", "2d", "linear", "elastic"), (2, "newmark", "2d", "linear", "elastic"),
    (3, "newmark", "2d", "linear", "elastic"), (1, "newmark", "3d", "linear", "elastic"),
    (2, "quasi_static", "3d", "linear", "elastic"), (2, "backward_euler", "2d", "linear", "elastic"),
    (1, "newmark", "2d", "gimp", "elastic"), (2, "quasi_static", "2d", "gimp", "elastic"),
    (2, "newmark", "3d", "gimp", "elastic"), (1, "quasi_static", "2d", "linear", "j2"),
    (2, "newmark", "2d", "gimp", "j2"), (1, "newmark", "2d", "bspline", "elastic"),
    (3, "quasi_static", "2d", "bspline", "j2"), (2, "newmark", "3d", "bspline", "elastic")]] + [
    (1, "quasi_static", "2d", "linear", "elastic", "plane_stress"),
    (2, "newmark", "2d", "linear", "j2", "plane_stress"),
    (1, "quasi_static", "2d", "linear", "elastic", "axisymmetric"),
    (2, "newmark", "2d", "linear", "j2", "axisymmetric"),
    (1, "quasi_static", "2d", "linear", "j2finite", "axisymmetric"),
    (2, "newmark", "3d", "linear", "j2finite", "default"),
    # the momentum formulation (Sulsky & Kaul 3.2.1): Jacobian M c + K R
    (1, "newmark", "2d", "linear", "elastic", "momentum"),
    (3, "newmark", "2d", "linear", "elastic", "momentum"),
    (2, "backward_euler", "2d", "bspline", "j2", "momentum"),
    (2, "newmark", "2d", "linear", "j2", "axisymmetric momentum"),
    (2, "newmark", "3d", "linear", "j2finite", "momentum"),
    # HHT-alpha: (1 + alpha) K + M / (beta dt^2), and the projection in the momentum formulation
    (1, "hht", "2d", "linear", "elastic", "default"), (2, "hht", "2d", "bspline", "j2", "default"),
    (1, "hht", "2d", "gimp", "elastic", "default"),
    (2, "hht", "3d", "linear", "elastic", "default"), (1, "hht", "2d", "linear", "j2", "axisymmetric"),
    (2, "hht", "2d", "linear", "elastic", "momentum"),
    # axes one cell wide: clipped GIMP and B-spline stencils (particles grouped by their whole node list)
    (1, "newmark", "2d", "linear", "elastic", "onecell"), (2, "newmark", "2d", "gimp", "elastic", "onecell"),
    (2, "quasi_static", "2d", "bspline", "elastic", "onecell"),
    (2, "quasi_static", "3d", "linear", "elastic", "onecell"),
    (1, "newmark", "3d", "gimp", "elastic", "onecell"), (2, "newmark", "3d", "bspline", "elastic", "onecell"),
    # F-bar (pimpm.kernels.fbar): the cell coupling of the volume average, every kinematics
    # that takes it, both hyperelastic models and both J2 models
    (1, "quasi_static", "2d", "linear", "elastic", "fbar"), (2, "quasi_static", "2d", "gimp", "j2finite", "fbar"),
    (3, "quasi_static", "2d", "gimp", "j2", "fbar"), (2, "newmark", "2d", "bspline", "j2finite", "fbar"), (2, "hht", "2d", "gimp", "elastic", "axisymmetric fbar"),
    (1, "quasi_static", "2d", "linear", "j2finite", "axisymmetric fbar"),
    (2, "newmark", "3d", "gimp", "elastic", "fbar"), (3, "quasi_static", "3d", "linear", "j2finite", "fbar"),
    (2, "backward_euler", "2d", "gimp", "elastic", "onecell fbar"),
    # F-bar on the nodes: the node coupling, summed over the ranks (2x2 process grid included)
    (1, "quasi_static", "2d", "gimp", "j2finite", "fbarnodes"), (3, "quasi_static", "2d", "gimp", "j2", "fbarnodes"),
    (4, "quasi_static", "2d", "linear", "j2finite", "axisymmetric fbarnodes"),
    (2, "hht", "2d", "bspline", "elastic", "axisymmetric fbarnodes"),
    (2, "newmark", "3d", "gimp", "elastic", "fbarnodes"), (3, "quasi_static", "3d", "linear", "j2finite", "fbarnodes")]


def _jacobian_args(integrator, dim, shape, material, kinematics):
    return [integrator, dim, shape, material] + ([] if kinematics == "default" else kinematics.split())


#: the cases of a rank count run as one MPI job (tests/mpi/batch.py)
JACOBIAN_CHECKS = BatchedChecks("jacobian_check.py", [(case[0], _jacobian_args(*case[1:]))
                                                      for case in JACOBIAN_CASES])


@pytest.mark.mpi
@pytest.mark.parametrize("nranks,integrator,dim,shape,material,kinematics", JACOBIAN_CASES)
def test_assembled_jacobian_matches_finite_differences(nranks, integrator, dim, shape, material,
                                                       kinematics):
    proc = JACOBIAN_CHECKS.result(nranks, _jacobian_args(integrator, dim, shape, material, kinematics))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    error = float(re.search(r" relative_error=(\S+)", proc.stdout).group(1))
    assert error < 1e-6
    assert "prescribed_rows_ok=True" in proc.stdout
    # the tangent is symmetric exactly when the problem says so (LDL^T is used then)
    asymmetry = float(re.search(r" asymmetry=(\S+)", proc.stdout).group(1))
    if "declared_symmetric=True" in proc.stdout:
        assert asymmetry < 1e-12
    else:
        assert asymmetry > 1e-6
    # the matrix-free shell product equals the assembled Jacobian times a vector
    shell = float(re.search(r"shell_product_relative_error=(\S+)", proc.stdout).group(1))
    assert shell < 1e-8
    # the COO assembly equals PETSc's MatSetValuesLocal one (to the order of summation);
    # COO is in use wherever the formulation allows it (the velocity formulation)
    assert float(re.search(r"coo_csr_difference=(\S+)", proc.stdout).group(1)) < 1e-14
    assert ("coo_used=True" in proc.stdout) == ("momentum" not in kinematics)
    # the direct solver's matrix on the free dofs is the whole one's free block
    # (where the direct preset runs on COO: every velocity-formulation case)
    assert ("free_matrix=True" in proc.stdout) == ("momentum" not in kinematics)
    assert float(re.search(r"free_matrix_difference=(\S+)", proc.stdout).group(1)) < 1e-14


def test_transfers_conserve_mass_and_momentum_on_1_2_3_ranks():
    outputs = {}
    for n in (1, 2, 3):
        proc = run_mpi(n, [f"{HERE}/mpi/transfer_check.py"], timeout=300)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        outputs[n] = proc.stdout
    # with 3 ranks, ranks 1 and 2 start with no particles and rank 2 never gets any
    counts = re.search(r"local_counts=\[(.*?)\] after_move=\[(.*?)\]", outputs[3])
    assert counts.group(1).split(", ")[1:] == ["0", "0"]
    assert counts.group(2).split(", ")[2] == "0"
    # global sums agree between rank counts to round-off
    sums = {n: [float(v) for v in re.findall(r"-?\d+\.\d*(?:e[-+]?\d+)?", out.splitlines()[1])] for n, out in outputs.items()}
    assert all(len(v) == 3 for v in sums.values())     # mass and two momentum components
    for n in (2, 3):
        for a, b in zip(sums[n], sums[1]):
            assert abs(a - b) <= 1e-12 * max(abs(b), 1.0)


def test_a_rebalance_moves_nodal_values_to_their_nodes_on_1_to_4_ranks():
    """Grid.transfer_owned (the last step's grid fields and the velocity
    fields' carried state at a rebalance) through PETSc's natural ordering,
    without gathering the grid on any rank: every value reaches its node, and
    back, for 1, dim and 5 values a node in 2D and 3D."""
    for n in (1, 2, 3, 4):
        proc = run_mpi(n, [f"{HERE}/mpi/grid_transfer_check.py"], timeout=300)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "transfer_ok=True" in proc.stdout
        if n > 1:       # the second partition differs from the first
            assert "moved=True" in proc.stdout and "moved=False" not in proc.stdout
