"""Vigil: tell me, and show me, when something moves."""

__version__ = "0.1.0"
