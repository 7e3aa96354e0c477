"""mechval: cross-validation of multibody physics engines on planar linkages.

This package is the `core/` folder of the repository: the analytic reference
(kinematics, Newton–Euler), the harness's data types (scenario, mechanism,
signals) and the command line. Engine adapters live in `mechval.engines`.
"""

__version__ = "0.1.0"
