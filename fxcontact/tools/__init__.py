"""Rigid tools: analytic surfaces, surfaces of revolution of a line/arc profile, and faceted
(optionally Nagata-smoothed) meshes."""

from fxcontact.tools.base import MovedTool, Projection, RigidMotion, StagedMotion, Tool
from fxcontact.tools.revolved import RevolvedProfile

__all__ = ["MovedTool", "Projection", "RigidMotion", "RevolvedProfile", "StagedMotion", "Tool"]
