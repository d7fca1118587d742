"""Rigid tools: analytic surfaces and faceted (optionally Nagata-smoothed) meshes."""

from fxcontact.tools.base import Projection, RigidMotion, Tool

__all__ = ["Projection", "RigidMotion", "Tool"]
