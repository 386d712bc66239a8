"""demkit's version (also in pyproject.toml): checkpoints record it, and resume only with the same."""
__version__ = "0.1.0"
