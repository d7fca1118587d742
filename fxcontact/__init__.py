"""fxcontact: nodal penalty contact against rigid tools for FEniCSx (dolfinx 0.5.2)."""

__version__ = "0.1.0"
