"""Kinematics of a material point: plane strain, plane stress, axisymmetric
and 3D, each a small object that gives the deformation increment, the
reference volume, the stress update at the material point and the extra
residual and tangent terms of its geometry. Chosen by lookup
(:func:`make_kinematics`), never by a flag tested in many places.

All arrays are per particle, vectorised. ``radius`` is the particle radius
at t (axisymmetric; None otherwise), ``displacement`` a callable returning
the particles' displacement over the step (n, dim), evaluated only where a
kinematics needs it (the axisymmetric hoop stretch).
"""
import numpy as np

from . import assembly
from .kernels import particle_step
from .materials import tensors


class PlaneStrain:
    """2D with F33 = 1 (also the base of the other kinematics)."""

    name = "plane_strain"
    #: plane stress solves F33 at every particle, the others never change it
    solves_thickness = False
    #: the code of this kinematics in the compiled kernels (pimpm.kernels.particle_step)
    kernel_code = particle_step.GENERAL

    def reference_volume(self, x, volume):
        """Particle volume from the seeded area (2D) or volume (3D)."""
        return volume

    def radius(self, x):
        """Particle radius for the hoop terms (axisymmetric only)."""
        return None

    def deformation_increment(self, grad_u, radius, displacement):
        """F_inc = 1 + grad u (G&W step 5), (n, 3, 3)."""
        return assembly.deformation_increment(grad_u)

    def internal_force_pairs(self, sigma, F_inc, G, S, volume, radius):
        """Per (particle, node) internal force (n, nn, dim): V_p P_p G_ip with
        P = J_inc sigma F_inc^-T relative to the configuration at t (volume at
        t), or with ``F_inc`` None the current stress over current volumes
        (explicit MPM, eq. 6)."""
        dim = G.shape[2]
        P = (sigma[:, :dim, :dim] if F_inc is None
             else assembly.incremental_first_piola(sigma, F_inc, dim))
        return assembly.internal_force_pairs(P, G, volume)

    def extra_stiffness(self, sigma, c, F_inc, G, S, volume, radius):
        """Stiffness blocks (n, nn*dim, nn*dim) the geometry adds to the
        in-plane ones, or None."""
        return None

    def element_tangents(self, sigma, c, F_inc, G, S, volume, radius):
        """Per-particle stiffness blocks (n, nn*dim, nn*dim): material +
        geometric stiffness of G&W step 2, plus the geometry's own terms."""
        K = assembly.element_tangents(sigma, c, F_inc, G, volume)
        extra = self.extra_stiffness(sigma, c, F_inc, G, S, volume, radius)
        if extra is not None:
            K += extra
        return K


class ThreeD(PlaneStrain):
    """Full 3D: every component of F is in the grid's gradient."""

    name = "3d"


class PlaneStress(PlaneStrain):
    """2D with sigma33 = 0: the thickness stretch F33 is found at every
    particle, and the in-plane tangent is condensed so that Newton on the
    grid stays exact."""

    name = "plane_stress"
    solves_thickness = True
    kernel_code = particle_step.PLANE_STRESS


class Axisymmetric(PlaneStrain):
    """2D in (r, z) = (x, y): the hoop stretch (r + u_r) / r, volumes of
    revolution (area x 2 pi r) and the hoop terms of the internal force and
    of the tangent."""

    name = "axisymmetric"
    kernel_code = particle_step.AXISYMMETRIC

    def reference_volume(self, x, volume):
        return volume * 2.0 * np.pi * x[:, 0]       # area x 2 pi r (x is the radius)

    def radius(self, x):
        return x[:, 0].copy()

    def deformation_increment(self, grad_u, radius, displacement):
        F_inc = assembly.deformation_increment(grad_u)
        F_inc[:, 2, 2] = 1.0 + displacement()[:, 0] / radius    # hoop stretch (r + u_r) / r
        return F_inc

    def internal_force_pairs(self, sigma, F_inc, G, S, volume, radius):
        pairs = super().internal_force_pairs(sigma, F_inc, G, S, volume, radius)
        if F_inc is None:
            F_inc = np.broadcast_to(np.eye(3), sigma.shape)
        pairs[:, :, 0] += assembly.hoop_force_pairs(sigma, F_inc, S, volume, radius)
        return pairs

    def extra_stiffness(self, sigma, c, F_inc, G, S, volume, radius):
        return assembly.hoop_tangents(sigma, c, F_inc, G, S, volume, radius)


#: input name -> kinematics class
KINEMATICS = {cls.name: cls for cls in (PlaneStrain, PlaneStress, Axisymmetric, ThreeD)}


def make_kinematics(name):
    return KINEMATICS[name]()


def inverted_count(F_inc):
    """Particles whose increment inverts them (full 3x3 det: an axisymmetric
    hoop stretch or a plane-stress thickness can invert too)."""
    return int(np.sum(~(tensors.det(F_inc) > 0.0)))
