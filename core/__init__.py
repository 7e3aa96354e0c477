"""mechval: cross-validation of multibody physics engines on planar linkages.

This package is the `core/` folder of the repository, the model every other
layer builds on: scenario, mechanism, the adapter contract, the analytic
reference (kinematics, Newton–Euler), signals, comparison, health, audit,
analysis. Engine adapters live in `mechval.engines`, reports in
`mechval.reports`, and the harness on top of them (command line, runner,
cost sweeps, baselines) in `mechval.harness`.
"""

__version__ = "0.1.0"
