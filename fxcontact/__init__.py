"""fxcontact: nodal penalty contact against rigid tools for FEniCSx (dolfinx 0.5.2).

Everything a forming or contact computation needs is importable from the package itself::

    import fxcontact as fx
    sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K=50.0, m=0.15))

The submodules (``fxcontact.simulation``, ``fxcontact.tools.analytic``, …) stay importable and
hold the lower-level functions (kernels and their numpy twins, projections, compatibility
helpers). Section numbers such as "THEORY §3.4" refer to the theory manual ``docs/theory.md``;
``docs/architecture.md`` shows how the pieces fit together.

Public API (name, its submodule, what it is):

{api}
"""

# The public API, imported explicitly (a new name: its import here and its line in _API)
from fxcontact import _legacy
from fxcontact._version import __version__  # noqa: E402
from fxcontact.checkpoint import CheckpointError, PerVertex, latest_checkpoint
from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Coulomb, Frictionless, Norton, ShearLimit, Tresca
from fxcontact.contact.nodal import FORMULATIONS, FRICTION_MODES, SCHEMES, NodalContact
from fxcontact.contact.penalty import Penalty, penalty_from_beta
from fxcontact.contact.springs import NodalSprings
from fxcontact.contact.view import ContactNodes
from fxcontact.element.dual import DualStress
from fxcontact.idle import IdleRotation
from fxcontact.heat import AirExchange, HeatProblem, ThermalMaterial
from fxcontact.io import figure, plot_flow_curves, plot_pressure_profile, render_png
from fxcontact.io.outputs import OutputError
from fxcontact.kinematics import CartesianUpdate, CylindricalUpdate, RingAxisUpdate
from fxcontact.materials import (FlowStress, HanselSpittel, LinearElastic, Material, NortonHoff,
                                 PowerHardening, TabulatedFlowStress, Viscoplastic)
from fxcontact.mesh_health import simplex_measures
from fxcontact.meshing import (BILLET_TAGS, BLOCK_TAGS, DRAWING_BAR_TAGS, RING_TAGS, block,
                               cylinder_billet, drawing_bar, gmsh_session, ring,
                               sector_plane_normals, structured_ring)
from fxcontact.newton.problem import (ContactProblem, ContributorError, NodalNonlinearProblem,
                                      NodalTerms, NonlinearProblem)
from fxcontact.newton.retry import IncrementError, MeshInversionError
from fxcontact.newton.solver import (LINE_SEARCHES, MATERIAL_TANGENTS, ContactNewtonSolver,
                                     NewtonSolver, SolveInfo, SolverOptions)
from fxcontact.power import PlasticDissipation, on_configuration, penalty_power, plastic_dissipation
from fxcontact.protocols import Contributor, Controller
from fxcontact.simulation import VOLUME_CORRECTIONS, IncrementResult, Simulation
from fxcontact.spaces import MixedSpace, facets_with_tags
from fxcontact.steady import steady_window
from fxcontact.thermal import HeatSetup, ToolHeat, WorkpieceHeat
from fxcontact.symmetry import SymmetryPlanes
from fxcontact.theory.forming import (avitzur_f, drawing_ideal_stress, drawing_mean_strain_rate,
                                      drawing_optimal_angle, drawing_sachs_stress, drawing_theory,
                                      drawing_upper_bound, flow_stress,
                                      ring_compression_upper_bound, ring_rolling_feed_window,
                                      ring_rolling_force, upsetting_slab_coulomb,
                                      upsetting_upper_bound)
from fxcontact.tools.analytic import Cone, Cylinder, Plane, Sphere
from fxcontact.tools.base import (ControlledMotion, MovedTool, Projection, RigidMotion,
                                  StagedMotion, Tool)
from fxcontact.tools.faceted import FacetedTool, check_surface, read_surface
from fxcontact.tools.revolved import (RevolvedProfile, die_profile, faceted_revolved,
                                      grooved_roll_profile)

_legacy.install()      # the former module names (fxcontact.solver, ...), with a warning


def __getattr__(name):
    """Former top-level names that moved (``fxcontact.RingCentring``), with a warning."""
    return _legacy.moved_name(name)


# One line per public name: name -> (submodule, one-line description), for help(fxcontact)
_API = {
    # time stepping and spaces
    "Simulation": ("simulation", "increment loop: BCs, contributors, cut-back, outputs (§1.5)"),
    "IncrementError": ("newton.retry", "raised when an increment fails after its cut-backs"),
    "IncrementResult": ("simulation", "outcome of one accepted increment (history row + info)"),
    "MeshInversionError": ("newton.retry", "raised when an element would turn inside out even "
                           "after the cut-backs"),
    "OutputError": ("io.outputs", "raised when writing the history or the VTK series fails"),
    "CheckpointError": ("checkpoint", "a checkpoint that is missing, incomplete, of another "
                        "version, mesh or set-up"),
    "PerVertex": ("checkpoint", "per-vertex contributor state saved in a checkpoint"),
    "latest_checkpoint": ("checkpoint", "the newest complete checkpoint in a directory"),
    "simplex_measures": ("mesh_health", "signed volume and shape quality of simplices"),
    "VOLUME_CORRECTIONS": ("simulation", "corrections of the accumulated volume error (§1.5)"),
    "SymmetryPlanes": ("symmetry", "symmetry planes of any orientation, imposed exactly (§1.6)"),
    "MixedSpace": ("spaces", "MINI (or Taylor-Hood) velocity-pressure space, vertex maps (§1.3)"),
    "facets_with_tags": ("spaces", "facet indices carrying given tags"),
    # materials
    "Material": ("materials.laws", "base class of the constitutive laws"),
    "NortonHoff": ("materials.laws", "incompressible Norton-Hoff viscoplasticity (§1.1)"),
    "LinearElastic": ("materials.laws", "incremental linear elasticity, mixed pressure (§1.4)"),
    "Viscoplastic": ("materials.local", "viscoplasticity with a flow stress sigma0(strain, rate, "
                     "T) (§15): a flow-stress law and a regularisation"),
    "FlowStress": ("materials.flow", "base class of the flow-stress laws sigma0(strain, rate, T) "
                   "in MPa, with their Norton-Hoff pieces per rate interval"),
    "PowerHardening": ("materials.flow", "Norton-Hoff with power hardening, "
                       "sqrt3 K0 (eps0 + strain)^n (sqrt3 rate)^m"),
    "HanselSpittel": ("materials.flow", "Hansel-Spittel flow stress (Forge's nine-parameter "
                      "form, T in degrees C)"),
    "TabulatedFlowStress": ("materials.flow", "flow stress tabulated in (strain, rate, T), "
                            "read from a CSV; log-linear in the rate"),
    # heat in the workpiece
    "ThermalMaterial": ("heat.materials", "heat capacity rho*c, conductivity k (constant or of T), "
                        "Taylor-Quinney fraction, effusivity (§16)"),
    "AirExchange": ("heat.materials", "free-surface exchange: film coefficient, ambient, "
                    "linearised radiation (§16.3)"),
    "HeatProblem": ("heat.problem", "transient heat on the moving workpiece: lumped backward "
                    "Euler, sources, tools, air, energy balance (§16)"),
    "WorkpieceHeat": ("thermal", "the workpiece's temperature with the mechanics, staggered per "
                      "increment: plastic and friction heat, tools, air (§16.6)"),
    "ToolHeat": ("thermal", "a tool's temperature, contact coefficient h_c and effusivity"),
    "HeatSetup": ("thermal", "a process case's thermal set-up: workpiece material, initial "
                  "temperature, air, tools"),
    # contact
    "ContactBoundary": ("contact.boundary", "contact nodes and their lumped areas S_n (§1.3)"),
    "NodalContact": ("contact.nodal", "nodal penalty contact, four schemes (§2-§3)"),
    "ContactNodes": ("contact.view", "read-only per-node view of a contact (NodalContact.nodes): "
                     "gaps, normals, points, forces, tools, areas"),
    "SCHEMES": ("contact.nodal", "names of the contact time-integration schemes (§3)"),
    "penalty_from_beta": ("contact.penalty", "penalty rho from the dimensionless beta (§2.5)"),
    "FRICTION_MODES": ("contact.nodal", "implicit or explicit friction (§9.4)"),
    "FORMULATIONS": ("contact.nodal", "contact in velocities (Simulation) or displacements"),
    "Frictionless": ("contact.friction", "no tangential stress (the default law, §9)"),
    "Coulomb": ("contact.friction", "Coulomb friction limited by Tresca (§9.2)"),
    "Tresca": ("contact.friction", "Tresca friction factor law tau = mbar k (§9.2)"),
    "Norton": ("contact.friction", "viscoplastic (Norton) friction (§9.2)"),
    "ShearLimit": ("contact.friction", "which shear flow stress k a Tresca limit uses: local "
                   "nodal rate, a given rate or a given k"),
    "Penalty": ("contact.penalty", "the penalty of a contact: rho, beta or a gap stiffness "
                "(§2.5)"),
    "NodalSprings": ("contact.springs", "nodal springs/dashpots: the smallest nodal contributor"),
    "Contributor": ("protocols", "what add_contributor takes: evaluate(w, jacobian), stable()"),
    "Controller": ("protocols", "what add_controller takes: optional hooks only"),
    # tools and their motions
    "Tool": ("tools.base", "base class of rigid tools (projection, motion)"),
    "Projection": ("tools.base", "result of a projection: gap, normal, point, Hessian, flags"),
    "RigidMotion": ("tools.base", "translation and rotation of a tool (§4.2)"),
    "StagedMotion": ("tools.base", "piecewise-constant rigid motion, integrated exactly"),
    "MovedTool": ("tools.base", "any tool moved by a rigid motion from its t = 0 position"),
    "Plane": ("tools.analytic", "analytic plane (§4.1)"),
    "Sphere": ("tools.analytic", "analytic ball or spherical cavity (§4.1)"),
    "Cylinder": ("tools.analytic", "analytic cylinder (roll, mandrel) or bore (§4.1)"),
    "Cone": ("tools.analytic", "analytic cone or conical bore (drawing die) (§4.1)"),
    "RevolvedProfile": ("tools.revolved", "surface of revolution of a line/arc profile: dies, "
                        "grooved rolls (§4.1)"),
    "die_profile": ("tools.revolved", "drawing-die meridian profile: cone, fillet, land"),
    "grooved_roll_profile": ("tools.revolved", "grooved-roll meridian profile"),
    "faceted_revolved": ("tools.revolved", "triangulation of a revolved profile (whole or "
                         "mirror-symmetric sector)"),
    "FacetedTool": ("tools.faceted", "triangulated tool, flat or Nagata projection (§6-§8)"),
    "read_surface": ("tools.faceted", "read a tool surface (gmsh .msh, STL, OBJ)"),
    "check_surface": ("tools.faceted", "check a triangulated surface, naming bad items"),
    # configuration updates
    "CartesianUpdate": ("kinematics", "configuration update X = x + dt v"),
    "CylindricalUpdate": ("kinematics", "cylindrical update about an axis, ring rolling (§5)"),
    # meshes
    "cylinder_billet": ("meshing", "gmsh cylinder billet (full or quarter) with facet tags"),
    # process analysis
    "PlasticDissipation": ("power", "plastic dissipation of the current solution, for power "
                           "balances (§14.5)"),
    "plastic_dissipation": ("power", "one-off plastic dissipation integral (§14.5)"),
    "penalty_power": ("power", "work rate of the normal penalty forces of a NodalContact"),
    "on_configuration": ("power", "evaluate a function on another configuration of the mesh "
                         "(e.g. the start of the increment)"),
    "steady_window": ("steady", "steady-state detection: two consecutive windows of "
                      "increments with the same means"),
    "block": ("meshing", "gmsh block, optionally refined in a box, with facet tags"),
    "gmsh_session": ("meshing", "context manager: a clean gmsh model"),
    "BILLET_TAGS": ("meshing", "facet tags of cylinder_billet"),
    "BLOCK_TAGS": ("meshing", "facet tags of block"),
    "drawing_bar": ("meshing", "gmsh round bar with a drawn nose, whole or a sector, with tags"),
    "DRAWING_BAR_TAGS": ("meshing", "facet tags of drawing_bar"),
    "sector_plane_normals": ("meshing", "outward normals of a sector's symmetry planes"),
    "ring": ("meshing", "gmsh flat ring (eighth, quarter or full model) with facet tags"),
    "RING_TAGS": ("meshing", "facet tags of ring"),
    "structured_ring": ("meshing", "structured ring (n_theta x n_r x n_z), ring rolling"),
    # forming theory (validation references, pure numpy/scipy)
    "flow_stress": ("theory.forming", "flow stress of the Norton-Hoff law at a strain rate (§14.1)"),
    "upsetting_upper_bound": ("theory.forming", "upsetting mean die pressure, Tresca upper bound "
                              "(§14.5)"),
    "upsetting_slab_coulomb": ("theory.forming", "upsetting mean die pressure, Coulomb slab (§14.5)"),
    "ring_compression_upper_bound": ("theory.forming", "Avitzur's ring-compression calibration curve "
                                     "and die pressure (§14.5)"),
    # controlled and idle tools (fxcontact.idle), the ring's moving axis
    "ControlledMotion": ("tools.base", "tool motion with rates set per increment by a controller"),
    "IdleRotation": ("idle", "idle tool: rotation speed from zero torque about its axis"),
    "RingAxisUpdate": ("kinematics", "cylindrical update about the ring's current centre (§5)"),
    "ring_rolling_feed_window": ("theory.forming", "ring rolling: feed per revolution window "
                                 "(penetration, bite-in) (§14.4)"),
    "ring_rolling_force": ("theory.forming", "ring rolling: roll force 2kHLQ (§14.4)"),
    "drawing_ideal_stress": ("theory.forming", "drawing: ideal work sigma0 ln(A0/A1), a lower bound "
                             "(§14.2)"),
    "drawing_sachs_stress": ("theory.forming", "drawing stress, Sachs slab with Coulomb friction "
                             "(§14.2)"),
    "avitzur_f": ("theory.forming", "Avitzur's factor f(alpha) of the drawing upper bound (§14.2)"),
    "drawing_upper_bound": ("theory.forming", "Avitzur's upper bound of the drawing stress (Tresca, "
                            "land) (§14.2)"),
    "drawing_mean_strain_rate": ("theory.forming", "mean strain rate in a conical drawing die "
                                 "(§14.2)"),
    "drawing_optimal_angle": ("theory.forming", "die semi-angle minimising Avitzur's bound (§14.2)"),
    "drawing_theory": ("theory.forming", "drawing-stress band of a Norton-Hoff material (§14.2)"),
    # solver and assembly
    "SolverOptions": ("newton.solver", "Newton and linear solver settings"),
    "ContactNewtonSolver": ("newton.solver", "SNES Newton with a stable-active-set test (§3.6)"),
    "NewtonSolver": ("newton.solver", "former name of ContactNewtonSolver (the same class)"),
    "SolveInfo": ("newton.solver", "outcome of a Newton solve"),
    "LINE_SEARCHES": ("newton.solver", "globalisations of Newton: PETSc line searches and "
                      "'trust-region'"),
    "MATERIAL_TANGENTS": ("newton.solver", "Norton-Hoff tangents of Newton: 'auto', 'consistent', "
                          "'primal-dual'"),
    "DualStress": ("element.dual", "dual stress of the primal-dual Norton-Hoff Newton (§3.6)"),
    "NodalNonlinearProblem": ("newton.problem", "UFL residual/Jacobian plus nodal terms, MPI-safe"),
    "NonlinearProblem": ("newton.problem", "former name of NodalNonlinearProblem (the same class)"),
    "ContactProblem": ("newton.problem", "dolfinx's NonlinearProblem plus nodal contact: your own "
                       "dolfinx NewtonSolver or SNES"),
    "NodalTerms": ("newton.problem", "per-vertex residual entries and 3x3 Jacobian blocks"),
    "ContributorError": ("newton.problem", "error raised by a nodal contributor on any rank"),
    # outputs and console
    "render_png": ("io.series", "offscreen picture of the mesh coloured by a cell field"),
    "figure": ("io.series", "a matplotlib figure saved to a PNG when its with-block ends"),
    "plot_flow_curves": ("io.flow_curves", "flow curves of a flow-stress law: sigma0 against "
                         "the strain for several rates and temperatures"),
    "plot_pressure_profile": ("io.series", "nodal contact pressures against Hertz's elliptic profile"),
    "configure_logging": ("console", "console of a script: rank 0, --verbose/--quiet"),
    "add_verbosity_arguments": ("console", "add --verbose/--quiet to an argparse parser"),
}

__all__ = ["__version__", *_API]   # tests/test_api.py: every name imported above

__doc__ = __doc__.format(api="\n".join(
    f"* {name} ({mod}): {text}" for name, (mod, text) in _API.items()))

