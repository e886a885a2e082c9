"""The version, a module of its own: every layer may name it, and it imports nothing."""

__version__ = "0.1.0"
