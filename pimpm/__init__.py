"""pimpm: parallel implicit Material Point Method on PETSc."""
__version__ = "0.1.0"
