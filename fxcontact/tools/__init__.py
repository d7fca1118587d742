"""Rigid tools: analytic surfaces and faceted (optionally Nagata-smoothed) meshes."""

from fxcontact.tools.base import MovedTool, Projection, RigidMotion, StagedMotion, Tool

__all__ = ["MovedTool", "Projection", "RigidMotion", "StagedMotion", "Tool"]
