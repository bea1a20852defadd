"""Kinematics of a material point: plane strain, plane stress, axisymmetric
and 3D, each a small object that names its code in the compiled kernels
(:mod:`pimpm.kernels.particle_step`, where the deformation increment, the
thickness solve, the hoop terms of the internal force and of the tangent
live), its reference volume and the particle radius the hoop terms use.
Chosen by lookup (:func:`make_kinematics`), never by a flag tested in many
places. Their numpy references: tests/reference/kinematics.py."""
import numpy as np

from .kernels import particle_step


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


class ThreeD(PlaneStrain):
    """Full 3D: every component of F is in the grid's gradient."""

    name = "3d"


class PlaneStress(PlaneStrain):
    """2D with sigma33 = 0: the thickness stretch F33 is found at every
    particle, and the in-plane tangent is condensed so that Newton on the
    grid stays exact (:func:`pimpm.kernels.material_point.solve_thickness`)."""

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


#: input name -> kinematics class
KINEMATICS = {cls.name: cls for cls in (PlaneStrain, PlaneStress, Axisymmetric, ThreeD)}


def make_kinematics(name):
    return KINEMATICS[name]()
