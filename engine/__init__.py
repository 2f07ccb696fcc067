"""Numerical core: linkage model, constraints, first- and second-order analysis.

Pure numpy/scipy; nothing here knows about HTTP.
"""

__version__ = "0.1.0"
