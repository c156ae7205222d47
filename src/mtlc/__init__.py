"""mtlc: the Maintenance Task Language Compiler."""

__version__ = "0.1.0"
