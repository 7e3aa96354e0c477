"""mechval: cross-validation of multibody physics engines on planar linkages.

This package is the `core/` folder of the repository, what every other
layer builds on: the adapter contract (`mechval.adapter`, with the settings
types, `mechval.settings`), the model (`mechval.model`: scenario, scene,
mechanism), the exact reference (`mechval.reference`: closed forms, the
planar solver, dynamics), the judging of signals (`mechval.judging`:
comparison, health, energy, resultants) and the records (`mechval.records`:
signals, outcomes, audit, findings, outputs). Engine adapters live in `mechval.engines`, reports in
`mechval.reports`, and the harness on top of them (command line, runner,
cost sweeps, baselines) in `mechval.harness`.
"""

__version__ = "0.1.0"
