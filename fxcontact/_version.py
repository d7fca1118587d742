"""The version of fxcontact (written into checkpoints and manifests)."""

__version__ = "0.1.0"
