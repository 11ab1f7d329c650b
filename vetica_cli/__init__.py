"""vetica: tapping-mode AFM on viscoelastic (SLS) surfaces, and the VETICA extraction."""

__version__ = "0.1.0"
