"""The input schema's vocabulary: the keys of every section and the names
each choice accepts (the swappable pieces' registries give theirs)."""
from ..integrators import INTEGRATORS as _INTEGRATOR_REGISTRY
from ..kinematics import KINEMATICS as _KINEMATICS_REGISTRY
from ..materials import MODELS
from ..presets import PRESETS
from ..shape import SHAPES


FORMULATIONS = ("velocity", "momentum")
SHAPE_FUNCTIONS = tuple(SHAPES)
# GIMP converges under refinement of h and dt; linear does not once particles
# cross cells (docs/VALIDATION.md, Convergence under refinement)
DEFAULT_SHAPE_FUNCTIONS = "gimp"
BOUNDARY_TYPES = ("free", "fixed", "roller", "symmetry")
BOUNDARY_ALIASES = {"symmetry": "roller"}
KINEMATICS = {2: tuple(k for k in _KINEMATICS_REGISTRY if k != "3d"), 3: ("3d",)}
MATERIAL_MODELS = tuple(MODELS)
GEOMETRY_TYPES = ("box", "ball", "cylinder", "half_space", "mesh", "particles", "surface")
#: geometries only a rigid body may have (a half-space is clipped to the grid; a
#: surface mesh, pimpm.surfaces, bounds no volume of its own)
RIGID_ONLY_GEOMETRIES = ("half_space", "surface")
#: geometries a contact law (frictionless, friction) can meet: those with a surface
CONTACT_GEOMETRIES = ("box", "ball", "cylinder", "half_space", "mesh", "surface")
FILE_GEOMETRIES = ("mesh", "particles")
DEFAULT_PARTICLES_PER_ELEMENT = 2
INTEGRATORS = tuple(_INTEGRATOR_REGISTRY)
STRESS_UPDATES = ("musl", "usl", "usf")
AXES = ("x", "y", "z")
DEFAULT_PARTICLES_PER_CELL = 2
DEFAULT_OUTPUT_DIRECTORY = "pimpm_output"
BBOX_RELATIVE_TOLERANCE = 1e-12

TOP_KEYS = ("title", "functions", "grid", "kinematics", "materials", "bodies", "contact", "loads", "time",
            "solver", "parallel", "output")
GRID_KEYS = ("lower", "upper", "cells", "shape_functions", "boundary", "weak_node_fraction")
#: nodes with less support than this fraction of a cell are extended out (GIMP, B-splines; pimpm.weak_nodes)
DEFAULT_WEAK_NODE_FRACTION = 0.05
ELASTIC_KEYS = ("shear_modulus", "bulk_modulus", "youngs_modulus", "poisson_ratio")
#: parameters of all models, in registry order (each model declares its own)
MODEL_PARAMETER_KEYS = tuple(dict.fromkeys(k for m in MODELS.values() for k in m.parameters))
MATERIAL_KEYS = ("model", "density", "f_bar", "f_bar_blend") + ELASTIC_KEYS + MODEL_PARAMETER_KEYS
#: F-bar (pimpm.fbar) where a material does not say: off, measured in
#: docs/VALIDATION.md ("Volumetric locking and F-bar"). Averaged on the nodes it
#: removes the pressure scatter of the plastic upsetting and its loads settle
#: sooner under refinement, but on the 1 mm grid its frictional loads fall below
#: the frictionless one (too soft), it costs 2-3x in 2D and 4.5x in 3D at 1 mm, and
#: its 3D tangent would not fit in memory at 0.5 mm
DEFAULT_F_BAR = False
#: what F-bar averages the volume change over (pimpm.fbar): the particles of a
#: cell, or the nodes' smooth average; ``f_bar: true`` means the first
F_BAR_AVERAGES = ("cells", "nodes")
#: the particle's own share in the volume change its material sees with F-bar
#: (det F_bar = J_bar^(1 - blend) J^blend) where a material does not say, per
#: average: on the nodes the pure average leaves the particles' own volume
#: changes free and Newton wanders (docs/VALIDATION.md, "Volumetric locking and F-bar")
DEFAULT_F_BAR_BLEND = {"cells": 0.0, "nodes": 0.1}
BODY_KEYS = ("name", "material", "rigid", "geometry", "particles_per_cell",
             "velocity", "function", "constrain", "contact", "friction_coefficient",
             "contact_stiffness", "slip_tolerance", "tangential_stiffness")
#: how bodies in a contact pair meet (pimpm.terms.pairs): bonded (one velocity
#: field), frictionless or friction (Coulomb friction with friction_coefficient)
CONTACT_LAWS = ("bonded", "frictionless", "friction")
#: how a rigid body meets the material (pimpm.terms): bonded (it prescribes
#: the nodes its particles touch), frictionless or friction (unilateral
#: contact at the body's surface, Coulomb friction with friction_coefficient)
#: or tied (welded at the body's surface from the first touch: it pulls as
#: well as pushes and never slides)
TOOL_LAWS = CONTACT_LAWS + ("tied",)
#: the contact penalty per unit area is contact_stiffness x (largest P-wave modulus) / h
DEFAULT_CONTACT_STIFFNESS = 100.0
#: Coulomb's law regularized (pimpm.kernels.contact.contact_point): a sticking point's
#: tangential stiffness is mu p / (slip_tolerance h), at most tangential_stiffness x
#: (largest P-wave modulus) / h; docs/VALIDATION.md measures what each costs
DEFAULT_SLIP_TOLERANCE = 1e-3
DEFAULT_TANGENTIAL_STIFFNESS = 0.3
#: the contact pairs' penalty (pimpm.terms.pairs) grows smoothly over its first
#: pair_onset x h of penetration (docs/VALIDATION.md: what it buys Newton)
DEFAULT_PAIR_ONSET = 1e-4
GEOMETRY_KEYS = {"box": ("type", "lower", "upper"), "ball": ("type", "center", "radius"),
                 "cylinder": ("type", "lower", "upper", "axis", "center", "radius"),
                 "half_space": ("type", "point", "normal"),
                 "mesh": ("type", "file", "particles_per_element", "scale", "offset"),
                 "surface": ("type", "file", "scale", "offset", "flip_normals"),
                 "particles": ("type", "file", "scale", "offset")}
#: the most step cuts a step may take (time.max_cuts; each halves the step)
MAX_CUTS = 50
TIME_KEYS = ("integrator", "dt", "end_time", "gravity", "gravity_function", "dt_initial", "ramp_factor",
             "max_cuts", "easy_newton_iterations", "max_particle_displacement", "cfl",
             "stress_update", "formulation") + tuple(
    dict.fromkeys(k for cls in _INTEGRATOR_REGISTRY.values() for k in cls.parameters))
SOLVER_KEYS = ("preset", "fallback", "fallback_max_dofs", "convergence", "petsc", "free_dofs_only", "reuse_factorization",
               "linear_predictor")
PARALLEL_KEYS = ("balance", "rebalance_threshold")
CONVERGENCE_KEYS = ("test", "displacement_tolerance", "energy_tolerance")
SOLVER_PRESETS = tuple(PRESETS)
CONVERGENCE_TESTS = ("petsc", "guilkey_weiss")
OUTPUT_KEYS = ("directory", "every", "checkpoint_every")
