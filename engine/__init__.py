"""Numerical core: linkage model, constraints, first- and second-order analysis.

Pure numpy/scipy (and the Clarabel conic solver for prestress stability); nothing here knows
about HTTP.
"""

__version__ = "0.1.0"
